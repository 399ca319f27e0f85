"""A fake SUMO for unit tests of the loop's stages: the straight road of
networks/straight, lane `WE_0` along +x at y = -5.25 m, no junctions or lights. Humans
drive at constant speed; platoon vehicles are placed (planar) or driven at their
commanded speed (lane)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.loop.ports import FloatArray, LaneOccupant, RouteContext, StandingVehicle
from platoon_sumo.world import LinkAhead, VehicleAhead, WorldSnapshot

LANE = "WE_0"
LANE_Y_M = -5.25


@dataclass
class FakeVehicle:
    x_m: float
    y_m: float = LANE_Y_M
    yaw_rad: float = 0.0
    speed_mps: float = 0.0
    length_m: float = 4.5
    width_m: float = 1.8
    sumo_drives: bool = True
    lane_id: str = LANE
    standing_s: float = 0.0


class FakeBackend:
    def __init__(self, dt_s: float = 0.1) -> None:
        self.dt_s = dt_s
        self.time = 0.0
        self.vehicles: dict[str, FakeVehicle] = {}
        self.queued: list[tuple[str, FakeVehicle]] = []
        self.departed: list[str] = []
        self.arrived: list[str] = []
        self.removed: list[tuple[str, bool]] = []
        self.lateral_speeds: dict[str, float] = {}
        self.held_lateral: list[str] = []
        self.waiting_behind: dict[str, tuple[str, float]] = {}
        """`sideways_waits`: who a test says waits behind a car changing lanes."""
        self.vanished: list[str] = []
        """Vehicles someone else took out of SUMO since the last step."""
        self.speed_commands: dict[str, float] = {}
        self.lane_requests: dict[str, int] = {}
        self.collisions: list[tuple[str, str, str]] = []
        self.yields: dict[str, list[str]] = {}
        """Per vehicle: the vehicles SUMO's right of way makes it yield to."""
        self.taking_right_of_way: dict[str, bool] = {}
        self.fail_moves_beyond_y_m = 10.0
        self.standing: list[StandingVehicle] = []

    # --------------------------------------------------------------- test helpers
    def add_human(self, vid: str, x_m: float, speed_mps: float) -> None:
        self.vehicles[vid] = FakeVehicle(x_m, speed_mps=speed_mps)

    # --------------------------------------------------------------- Backend
    @property
    def time_s(self) -> float:
        return self.time

    def step(self) -> None:
        self.time = round(self.time + self.dt_s, 9)
        self.departed = [vid for vid, _ in self.queued]
        for vid, v in self.queued:
            self.vehicles[vid] = v
        self.queued = []
        self.arrived = []
        for vid, v in self.vehicles.items():
            if v.sumo_drives:
                v.speed_mps = self.speed_commands.get(vid, v.speed_mps)
                v.x_m += v.speed_mps * self.dt_s

    def snapshot(self, vehicle_ids: Sequence[str], radius_m: float) -> WorldSnapshot:
        centres = [self.vehicles[v] for v in vehicle_ids]
        ids = list(vehicle_ids) + [
            vid for vid, v in self.vehicles.items()
            if vid not in vehicle_ids
            and any(math.hypot(v.x_m - c.x_m, v.y_m - c.y_m) <= radius_m for c in centres)
        ]  # fmt: skip
        vs = [self.vehicles[v] for v in ids]
        arr = lambda f: np.array([getattr(v, f) for v in vs], dtype=np.float64)  # noqa: E731
        return WorldSnapshot(
            self.time, tuple(ids), arr("x_m"), arr("y_m"), arr("yaw_rad"), arr("length_m"),
            arr("width_m"), arr("speed_mps"), tuple(v.lane_id for v in vs),
            {v: i for i, v in enumerate(ids)},
        )  # fmt: skip

    def vehicle_count(self) -> int:
        return len(self.vehicles)

    def standing_vehicles(self, min_wait_s: float) -> list[StandingVehicle]:
        return [v for v in self.standing if v[4] >= min_wait_s]

    def largest_vehicle_m(self) -> float:
        return max((v.length_m + v.width_m for v in self.vehicles.values()), default=0.0)

    def add_vehicle(
        self, vehicle_id: str, edges: Sequence[str], type_id: str, depart_lane: int,
        depart_pos_m: float, sumo_drives: bool, steers: bool = False,
    ) -> None:  # fmt: skip
        self.queued.append((vehicle_id, FakeVehicle(depart_pos_m, sumo_drives=sumo_drives)))

    def lane_is_free(self, lane_id: str, from_m: float, to_m: float) -> bool:
        return not any(from_m < v.x_m and v.x_m - v.length_m < to_m for v in self.vehicles.values())

    def lane_occupants(self, lane_id: str) -> list[LaneOccupant]:
        return [(vid, v.x_m, v.speed_mps, v.length_m) for vid, v in self.vehicles.items()]

    def next_junction_lane(self, vehicle_id: str) -> str:
        return ""

    def lane_shape(self, lane_id: str) -> FloatArray:
        return np.array([[0.0, LANE_Y_M], [3000.0, LANE_Y_M]])

    def lane_width(self, lane_id: str) -> float:
        return 3.5

    def departed_ids(self) -> tuple[str, ...]:
        return tuple(self.departed)

    def arrived_ids(self) -> tuple[str, ...]:
        return tuple(self.arrived)

    def removed_elsewhere(self) -> tuple[str, ...]:
        gone, self.vanished = tuple(self.vanished), []
        for vid in gone:
            self.vehicles.pop(vid, None)
        return gone

    def teleported_ids(self) -> tuple[str, ...]:
        return ()

    def sumo_collisions(self) -> Iterable[tuple[str, str, str]]:
        return list(self.collisions)

    def route_contexts(
        self, vehicle_ids: Sequence[str], horizons_m: Sequence[float], read_links: Sequence[bool]
    ) -> list[RouteContext]:
        out: list[RouteContext] = []
        for vid, horizon in zip(vehicle_ids, horizons_m, strict=True):
            me = self.vehicles[vid]
            ahead = [
                (v.x_m - v.length_m - me.x_m, oid, v.speed_mps)
                for oid, v in self.vehicles.items()
                if oid != vid and v.x_m > me.x_m
            ]
            near = min(ahead) if ahead else None
            leader = (
                VehicleAhead(near[1], near[0], near[2])
                if near is not None and near[0] <= horizon
                else None
            )
            out.append((None, leader, None))
        return out

    def link_ahead(self, vehicle_id: str, distance_m: float) -> LinkAhead | None:
        return None  # a straight road without junctions

    def move(
        self, vehicle_ids: Sequence[str], front_x_m: FloatArray, front_y_m: FloatArray,
        yaw_rad: FloatArray, speed_mps: FloatArray,
    ) -> dict[str, str]:  # fmt: skip
        failed = {}
        for i, vid in enumerate(vehicle_ids):
            if abs(front_y_m[i] - LANE_Y_M) > self.fail_moves_beyond_y_m:
                failed[vid] = f"cannot place '{vid}' off the road"
                continue
            v = self.vehicles[vid]
            v.x_m, v.y_m, v.yaw_rad = float(front_x_m[i]), float(front_y_m[i]), float(yaw_rad[i])
            v.speed_mps = float(speed_mps[i])
        return failed

    def set_speeds(self, vehicle_ids: Sequence[str], speed_mps: FloatArray) -> None:
        self.speed_commands.update(zip(vehicle_ids, map(float, speed_mps), strict=True))

    def request_lane_changes(self, requests: dict[str, int]) -> None:
        self.lane_requests.update(requests)

    def set_lateral_speeds(self, vehicle_ids: Sequence[str], speed_mps: FloatArray) -> None:
        self.lateral_speeds.update(zip(vehicle_ids, map(float, speed_mps), strict=True))

    def body_directions(
        self, vehicle_ids: Sequence[str], ahead_m: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        zeros = np.zeros(len(vehicle_ids))  # the fake's lane runs along +x
        return zeros, zeros

    def in_junctions(self, vehicle_ids: Sequence[str]) -> NDArray[np.bool_]:
        return np.zeros(len(vehicle_ids), dtype=np.bool_)  # the fake has no junctions

    def lane_room(self, vehicle_ids: Sequence[str]) -> tuple[FloatArray, FloatArray, FloatArray]:
        unbounded = np.full(len(vehicle_ids), np.inf)  # the fake's lane has no end
        return np.zeros(len(vehicle_ids)), unbounded, unbounded.copy()

    def bends_ahead(self, vehicle_ids: Sequence[str]) -> tuple[FloatArray, FloatArray]:
        unbounded = np.full((len(vehicle_ids), 1), np.inf)  # the fake's lane is straight
        return unbounded, unbounded.copy()

    def sumo_lateral_speeds(self, vehicle_ids: Sequence[str], offset_m: FloatArray) -> FloatArray:
        return np.full(len(vehicle_ids), np.nan)  # the fake hands no car over to SUMO

    def lane_change_landings(
        self,
        vehicle_ids: Sequence[str],
        offset_m: FloatArray,
        lateral_mps: FloatArray,
        speed_mps: FloatArray,
        dt_s: float,
    ) -> FloatArray:
        return np.full((len(vehicle_ids), 5), np.nan)  # the fake's lane is one: no jumps

    def hold_lateral(self, vehicle_ids: Sequence[str]) -> None:
        self.held_lateral.extend(vehicle_ids)

    def sideways_waits(
        self, vehicle_ids: Sequence[str], leaders: Sequence[VehicleAhead | None]
    ) -> dict[str, tuple[str, float]]:
        return {v: w for v, w in self.waiting_behind.items() if v in vehicle_ids}

    def junction_yields(self, vehicle_id: str) -> list[tuple[str, float]]:
        return [(f, self.vehicles[f].standing_s) for f in self.yields.get(vehicle_id, [])]

    def take_right_of_way(self, vehicle_id: str, take: bool) -> None:
        self.taking_right_of_way[vehicle_id] = take

    def remove(self, vehicle_id: str, arrived: bool) -> None:
        self.removed.append((vehicle_id, arrived))
        self.vehicles.pop(vehicle_id)
