"""The platoon vehicles in the network: one `Member` per vehicle, owned by the loop.

Stages read and write members only through the step context; hooks never see them
(they get frozen `VehicleRecord`s). `Fleet.remove` is the one way out of the run.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from platoon_sumo.actuation import Actuator
from platoon_sumo.control import Command, Controller
from platoon_sumo.path import RoutePath
from platoon_sumo.scenario import MemberPlan, PlatoonPlan
from platoon_sumo.world import LaneChangeAhead, LinkAhead, SignalAhead, VehicleAhead


@dataclass
class Member:
    """One platoon vehicle while it is in the network (pose of the model's reference
    point: rear axle for cars, wheel axle for robots)."""

    plan: MemberPlan
    platoon: PlatoonPlan
    controller: Controller
    actuator: Actuator
    path: RoutePath
    x_m: float
    y_m: float
    yaw_rad: float
    speed_mps: float = 0.0
    accel_mps2: float = 0.0
    route_s_m: float = 0.0
    """Front bumper's progress along the route path."""
    lateral_offset_m: float = 0.0
    command: Command = field(default_factory=lambda: Command(0.0))
    """What the controller asked for this step."""
    executed: Command = field(default_factory=lambda: Command(0.0))
    """What the supervisor let through (the actuator's input)."""
    supervisor_state: str = ""
    sumo_capped: bool = False
    signal: SignalAhead | None = None
    link_ahead: LinkAhead | None = None
    lane_change: LaneChangeAhead | None = None
    vehicle_ahead: VehicleAhead | None = None
    sensors: dict[str, Any] = field(default_factory=dict)
    """Latest message of each sensor, by name."""
    last_sensed_s: dict[str, float] = field(default_factory=dict)
    predecessor_id: str | None = None
    gap_to_predecessor_m: float | None = None
    predecessor_rays: int | None = None
    """Rays of this step's laser scan that returned from the predecessor (None: no new
    scan this step)."""

    @property
    def id(self) -> str:
        return self.plan.vehicle_id

    @property
    def platoon_id(self) -> str:
        return self.plan.platoon_id

    @property
    def index(self) -> int:
        return self.plan.index

    @property
    def front_offset_m(self) -> float:
        return self.platoon.config.vehicle.front_offset_m

    def front_bumper(self) -> tuple[float, float]:
        off = self.front_offset_m
        return self.x_m + off * math.cos(self.yaw_rad), self.y_m + off * math.sin(self.yaw_rad)

    def set_front_pose(self, front_x_m: float, front_y_m: float, yaw_rad: float) -> None:
        off = self.front_offset_m
        self.x_m = front_x_m - off * math.cos(yaw_rad)
        self.y_m = front_y_m - off * math.sin(yaw_rad)
        self.yaw_rad = yaw_rad


class Fleet:
    """The members in the network, in insertion order (deterministic)."""

    def __init__(self) -> None:
        self._members: dict[str, Member] = {}

    def add(self, member: Member) -> None:
        self._members[member.id] = member

    def remove(self, vehicle_id: str) -> Member | None:
        return self._members.pop(vehicle_id, None)

    def get(self, vehicle_id: str) -> Member | None:
        return self._members.get(vehicle_id)

    def __contains__(self, vehicle_id: object) -> bool:
        return vehicle_id in self._members

    def __iter__(self) -> Iterator[Member]:
        return iter(list(self._members.values()))

    def __len__(self) -> int:
        return len(self._members)

    def ids(self) -> list[str]:
        return list(self._members)

    def by_platoon(self) -> dict[str, list[Member]]:
        groups: dict[str, list[Member]] = {}
        for m in self._members.values():
            groups.setdefault(m.platoon_id, []).append(m)
        return groups
