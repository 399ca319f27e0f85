"""The platoon vehicles in the network, owned by the loop.

Their kinematic state lives in one array (`Fleet.kin`, a row per vehicle, a column per
quantity), so stages work on all vehicles at once (`Fleet.rows`, `Fleet.column`);
`Member` holds what is per vehicle by nature (its plan, controller, actuator, route,
messages) and reads and writes its row through properties. Stages read and write
members only through the step context; hooks never see them (they get the step's
`VehicleColumns` and `VehicleRecord`s). `Fleet.remove` is the one way out of the run.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.actuation import Actuator
from platoon_sumo.control import Command, Controller
from platoon_sumo.path import RoutePath
from platoon_sumo.scenario import MemberPlan, PlatoonPlan
from platoon_sumo.world import LaneChangeAhead, LinkAhead, SignalAhead, VehicleAhead

#: The columns of `Fleet.kin`. Pose is the vehicle model's reference point (rear axle
#: for cars, wheel axle for robots); `route_s_m` is the front bumper's progress along
#: the route path and `lateral_offset_m` its offset from it (left +).
KINEMATICS = (
    "x_m", "y_m", "yaw_rad", "speed_mps", "accel_mps2", "route_s_m", "lateral_offset_m",
    "front_offset_m",
)  # fmt: skip
X, Y, YAW, SPEED, ACCEL, ROUTE_S, LATERAL, FRONT_OFFSET = range(len(KINEMATICS))

T = TypeVar("T")


class _Column:
    """A member's value in one column of its fleet's state array."""

    def __init__(self, column: int) -> None:
        self.column = column

    def __get__(self, member: Member, owner: type | None = None) -> float:
        return float(member.fleet.kin[member.row, self.column])

    def __set__(self, member: Member, value: float) -> None:
        member.fleet.kin[member.row, self.column] = value


@dataclass(eq=False)
class Member:
    """One platoon vehicle while it is in the network; its kinematic state is its row
    of `fleet.kin` (see `KINEMATICS`)."""

    plan: MemberPlan
    platoon: PlatoonPlan
    controller: Controller
    actuator: Actuator
    path: RoutePath
    fleet: Fleet = field(repr=False)
    row: int
    x_m = _Column(X)
    y_m = _Column(Y)
    yaw_rad = _Column(YAW)
    speed_mps = _Column(SPEED)
    accel_mps2 = _Column(ACCEL)
    route_s_m = _Column(ROUTE_S)
    lateral_offset_m = _Column(LATERAL)
    front_offset_m = _Column(FRONT_OFFSET)
    command: Command = field(default_factory=lambda: Command(0.0))
    """What the controller asked for this step."""
    executed: Command = field(default_factory=lambda: Command(0.0))
    """What the supervisor let through (the actuator's input)."""
    supervisor_state: str = ""
    desired_accel_mps2: float = 0.0
    """The acceleration the last command asked for (what a V2V channel broadcasts)."""
    speed_sent_mps: float = 0.0
    """The speed handed to the actuator: the executed command after the powertrain."""
    sumo_capped: bool = False
    signal: SignalAhead | None = None
    link_ahead: LinkAhead | None = None
    lane_end_m: float | None = None
    """The end of its lane within its horizon, whose link is not read yet [m]
    (`loop.progress.link_ahead` reads it; None: read, or no lane end within reach)."""
    lane_change: LaneChangeAhead | None = None
    vehicle_ahead: VehicleAhead | None = None
    obstacle_ahead: VehicleAhead | None = None
    """Nearest footprint reaching into the corridor ahead (`loop.obstacles`)."""
    sidestep_m: float = 0.0
    """Sideways shift (left +) that clears a standing car reaching into the corridor,
    one of the two in a junction (`loop.obstacles`); 0: none."""
    sensors: dict[str, Any] = field(default_factory=dict)
    """Latest message of each sensor, by name."""
    last_sensed_s: dict[str, float] = field(default_factory=dict)
    predecessor_id: str | None = None
    gap_to_predecessor_m: float | None = None
    predecessor_rays: int | None = None
    """Rays of this step's laser scan that returned from the predecessor (None: no new
    scan this step)."""

    id: str = field(init=False)
    platoon_id: str = field(init=False)
    index: int = field(init=False)
    """The plan's vehicle id, platoon id and place in the platoon (copied: read by every
    stage every step)."""

    def __post_init__(self) -> None:
        self.id = self.plan.vehicle_id
        self.platoon_id = self.plan.platoon_id
        self.index = self.plan.index

    @property
    def link_distance_m(self) -> float | None:
        """Distance to the end of its lane where that end is within its horizon (on a
        lane), its link read or not [m]; None otherwise, or where the link was read and
        there is none (the route's end)."""
        return self.lane_end_m if self.link_ahead is None else self.link_ahead.distance_m

    def front_bumper(self) -> tuple[float, float]:
        off = self.front_offset_m
        return self.x_m + off * math.cos(self.yaw_rad), self.y_m + off * math.sin(self.yaw_rad)

    def set_front_pose(self, front_x_m: float, front_y_m: float, yaw_rad: float) -> None:
        off = self.front_offset_m
        self.x_m = front_x_m - off * math.cos(yaw_rad)
        self.y_m = front_y_m - off * math.sin(yaw_rad)
        self.yaw_rad = yaw_rad


class Fleet:
    """The members in the network, in insertion order (deterministic), and their
    kinematic state. Rows are never reused within a run, so a member's row is fixed."""

    def __init__(self, capacity: int = 16) -> None:
        self.kin: NDArray[np.float64] = np.zeros((max(capacity, 1), len(KINEMATICS)))
        self._members: dict[str, Member] = {}
        self._next_row = 0
        self._now: tuple[tuple[Member, ...], NDArray[np.int64]] | None = None
        """`members()` and their rows, until a member joins or leaves (every stage asks)."""
        self._fixed: dict[Hashable, Any] = {}
        """`fixed`'s values for `members()`."""

    def join(
        self,
        plan: MemberPlan,
        platoon: PlatoonPlan,
        controller: Controller,
        actuator: Actuator,
        path: RoutePath,
    ) -> Member:
        """A new member, at rest at the origin until its pose is set."""
        if self._next_row == len(self.kin):
            self.kin = np.concatenate([self.kin, np.zeros_like(self.kin)])
        self.kin[self._next_row] = 0.0
        member = Member(plan, platoon, controller, actuator, path, self, self._next_row)
        member.front_offset_m = platoon.config.vehicle.front_offset_m
        self._next_row += 1
        self._members[member.id] = member
        self._now = None
        return member

    def remove(self, vehicle_id: str) -> Member | None:
        self._now = None
        return self._members.pop(vehicle_id, None)

    def get(self, vehicle_id: str) -> Member | None:
        return self._members.get(vehicle_id)

    def __contains__(self, vehicle_id: object) -> bool:
        return vehicle_id in self._members

    def __iter__(self) -> Iterator[Member]:
        return iter(self.members())

    def __len__(self) -> int:
        return len(self._members)

    def ids(self) -> list[str]:
        return list(self._members)

    def members(self) -> tuple[Member, ...]:
        """The members in insertion order: the same tuple until one joins or leaves, so
        `rows` of it is known."""
        now = self._now
        if now is None:
            members = tuple(self._members.values())
            rows = self._rows_of(members)
            rows.flags.writeable = False
            now = self._now = (members, rows)
            self._fixed.clear()
        return now[0]

    def fixed(self, key: Hashable, build: Callable[[tuple[Member, ...]], T]) -> T:
        """`build(members())`, made again only once a member joins or leaves: for what
        stays the same while the same members drive (their sizes, horizons, controllers'
        classes), which the stages otherwise gathered member by member every step.
        `key` names the value; one that depends on a stage's own state (numbers it
        gives paths or groups) includes the stage."""
        members = self.members()
        found = self._fixed.get(key)
        if found is None:
            found = self._fixed[key] = build(members)
        return cast(T, found)

    def rows(self, members: Sequence[Member]) -> NDArray[np.int64]:
        """The rows of `members` in `kin` (read-only when `members` is `members()`)."""
        now = self._now
        if now is not None and members is now[0]:
            return now[1]
        return self._rows_of(members)

    @staticmethod
    def _rows_of(members: Sequence[Member]) -> NDArray[np.int64]:
        return np.fromiter((m.row for m in members), dtype=np.int64, count=len(members))

    def front_bumpers(self, rows: NDArray[np.int64]) -> tuple[NDArray[np.float64], ...]:
        """Front bumper (x, y) of the members in `rows`."""
        k = self.kin[rows]
        off = k[:, FRONT_OFFSET]
        return k[:, X] + off * np.cos(k[:, YAW]), k[:, Y] + off * np.sin(k[:, YAW])

    def set_front_poses(
        self,
        rows: NDArray[np.int64],
        front_x_m: NDArray[np.float64],
        front_y_m: NDArray[np.float64],
        yaw_rad: NDArray[np.float64],
    ) -> None:
        """Place the members in `rows` by their front bumpers."""
        off = self.kin[rows, FRONT_OFFSET]
        self.kin[rows, X] = front_x_m - off * np.cos(yaw_rad)
        self.kin[rows, Y] = front_y_m - off * np.sin(yaw_rad)
        self.kin[rows, YAW] = yaw_rad
