"""What stages share within a step, and what hooks receive: data, never the loop.

`StepContext` is the only thing stages exchange: the world read after the last SUMO
step, its footprints, the fleet and this step's events. The rule of which world a
controller sees is in the order of the stages (`cosim.py`): sensing and decisions use
the world read after the previous SUMO step; everything after the SUMO step reads the
new one.

Hooks get a frozen `RunContext` at the start, a `StepRecord` (the platoon vehicles
as columns and, when asked for, as immutable records; footprints, events) every step
and a `RunOutcome` at the end, always, even when the run fails.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.control import Command, Telemetry
from platoon_sumo.events import Event, EventKind
from platoon_sumo.loop.fleet import (
    ACCEL,
    FRONT_OFFSET,
    LATERAL,
    ROUTE_S,
    SPEED,
    YAW,
    Fleet,
    Member,
    X,
    Y,
)
from platoon_sumo.loop.ports import Backend
from platoon_sumo.scenario import MemberPlan, PlatoonPlan, RunPlan
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.world import SignalAhead, VehicleAhead, WorldSnapshot

FloatArray = NDArray[np.float64]


def empty_world(time_s: float) -> WorldSnapshot:
    none = np.empty(0)
    return WorldSnapshot(time_s, (), none, none, none, none, none, none, (), {})


@dataclass(frozen=True)
class RunContext:
    """What a run is, for hooks: fixed for the whole run."""

    plan: RunPlan
    dt_s: float
    begin_s: float
    end_s: float
    static_segments: FloatArray | None


@dataclass
class StepContext:
    """The state stages share. Stages append to `events`; `remove` takes a vehicle out."""

    run: RunContext
    backend: Backend
    rng: np.random.Generator
    fleet: Fleet = field(default_factory=Fleet)
    world: WorldSnapshot = field(default_factory=lambda: empty_world(0.0))
    footprints: FloatArray = field(default_factory=lambda: np.empty((0, 5)))
    world_before: WorldSnapshot | None = None
    """The world read one SUMO step before `world` (for what changed over a step)."""
    sensed_world: WorldSnapshot | None = None
    """The world this step's sensors observed (the previous step's)."""
    sensed_footprints: FloatArray | None = None
    events: list[Event] = field(default_factory=list)
    pending: list[PlatoonPlan] = field(default_factory=list)
    """Platoons not inserted yet (due ones wait for room on their first lane)."""
    waiting: dict[str, MemberPlan] = field(default_factory=dict)
    """Members handed to SUMO that have not departed yet."""
    queued: dict[str, tuple[PlatoonPlan, list[MemberPlan]]] = field(default_factory=dict)
    """Per inserted platoon, the members still to hand to SUMO one by one (the platoon
    did not fit on its first edge), in order."""
    steps: int = 0
    departed_total: int = 0
    arrived_total: int = 0

    @property
    def dt_s(self) -> float:
        return self.run.dt_s

    def emit(
        self,
        kind: EventKind,
        member: Member | str,
        other: str = "",
        detail: str = "",
        at_fault: str = "",
    ) -> None:
        if isinstance(member, Member):
            vid, pid = member.id, member.platoon_id
        else:
            vid, pid = member, ""
        # the backend's clock: stages after SUMO's step emit before the new world is read
        self.events.append(Event(self.backend.time_s, kind, vid, other, pid, detail, at_fault))

    def remove(self, member: Member, arrived: bool, reason: str = "") -> None:
        """The one way a platoon vehicle leaves the run before SUMO lets it arrive."""
        self.backend.remove(member.id, arrived)
        self.fleet.remove(member.id)
        if arrived:
            self.arrived_total += 1
            self.emit(EventKind.ARRIVED, member)
        else:
            self.emit(EventKind.REMOVED, member, detail=reason)


class VehicleRecord(NamedTuple):
    """One platoon vehicle at the end of a step (immutable; a named tuple because one is
    built per platoon vehicle per step, five times faster than a frozen dataclass)."""

    id: str
    platoon_id: str
    member_index: int
    """Place in the platoon (0: leader)."""
    role: str
    x_m: float
    y_m: float
    """Reference point (rear axle / wheel axle)."""
    yaw_rad: float
    front_x_m: float
    front_y_m: float
    speed_mps: float
    accel_mps2: float
    length_m: float
    route_s_m: float
    lateral_offset_m: float
    lane_width_m: float
    command: Command
    executed: Command
    supervisor_state: str
    signal: SignalAhead | None
    vehicle_ahead: VehicleAhead | None
    predecessor_id: str | None
    gap_to_predecessor_m: float | None
    predecessor_rays: int | None
    sensors: Mapping[str, Any]

    @property
    def scan(self) -> LaserScan | None:
        scan = self.sensors.get("laser")
        return scan if isinstance(scan, LaserScan) else None

    @property
    def telemetry(self) -> Telemetry | None:
        return self.command.telemetry


#: `VehicleRecord`'s fields held as float arrays in `VehicleColumns`.
NUMERIC_FIELDS = (
    "x_m", "y_m", "yaw_rad", "front_x_m", "front_y_m", "speed_mps", "accel_mps2", "length_m",
    "route_s_m", "lateral_offset_m", "lane_width_m",
)  # fmt: skip


@dataclass(frozen=True)
class VehicleColumns:
    """The step's platoon vehicles as columns, in the fleet's order: `VehicleRecord`'s
    fields, one entry per vehicle, the numbers (`NUMERIC_FIELDS`) as float arrays. Built
    once a step from the fleet's state array; recorders read it without a Python object
    per vehicle, and `records()` gives the same data as rows."""

    id: tuple[str, ...]
    platoon_id: tuple[str, ...]
    member_index: tuple[int, ...]
    role: tuple[str, ...]
    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    front_x_m: FloatArray
    front_y_m: FloatArray
    speed_mps: FloatArray
    accel_mps2: FloatArray
    length_m: FloatArray
    route_s_m: FloatArray
    lateral_offset_m: FloatArray
    lane_width_m: FloatArray
    command: tuple[Command, ...]
    executed: tuple[Command, ...]
    supervisor_state: tuple[str, ...]
    signal: tuple[SignalAhead | None, ...]
    vehicle_ahead: tuple[VehicleAhead | None, ...]
    predecessor_id: tuple[str | None, ...]
    gap_to_predecessor_m: tuple[float | None, ...]
    predecessor_rays: tuple[int | None, ...]
    sensors: tuple[Mapping[str, Any], ...]

    def __len__(self) -> int:
        return len(self.id)

    @cached_property
    def scans(self) -> tuple[LaserScan | None, ...]:
        """Each vehicle's latest laser scan (`VehicleRecord.scan`), or None."""
        return tuple(
            scan if isinstance(scan := sensors.get("laser"), LaserScan) else None
            for sensors in self.sensors
        )

    def records(self) -> tuple[VehicleRecord, ...]:
        """The same vehicles as `VehicleRecord`s (numbers as Python floats)."""
        fields = [
            getattr(self, name).tolist() if name in NUMERIC_FIELDS else getattr(self, name)
            for name in VehicleRecord._fields
        ]
        return tuple(map(VehicleRecord, *fields))


def vehicle_columns(fleet: Fleet) -> VehicleColumns:
    """Every member's record as columns, in the fleet's order."""
    members = fleet.members()
    kin = fleet.kin[fleet.rows(members)]
    ids, platoons, indices, roles, lengths = fleet.fixed("vehicle columns", _fixed_columns)
    x, y, yaw, off, route_s = (kin[:, c] for c in (X, Y, YAW, FRONT_OFFSET, ROUTE_S))
    # the front bumper with `math`'s cos and sin, as `Member.front_bumper` has it
    poses = zip(x.tolist(), y.tolist(), yaw.tolist(), off.tolist(), strict=True)
    front = [(a + o * math.cos(w), b + o * math.sin(w)) for a, b, w, o in poses]
    front_x, front_y = np.array(front, dtype=np.float64).reshape(-1, 2).T
    rows = [
        (
            m.path.lane_width_near(s), m.command, m.executed, m.supervisor_state, m.signal,
            m.vehicle_ahead, m.predecessor_id, m.gap_to_predecessor_m, m.predecessor_rays,
            dict(m.sensors),
        )
        for m, s in zip(members, route_s.tolist(), strict=True)
    ]  # fmt: skip
    (
        widths, commands, executed, supervisor, signals, aheads, predecessors, gaps, rays,
        sensors,
    ) = tuple(zip(*rows, strict=True)) if rows else ((),) * 10  # fmt: skip
    return VehicleColumns(
        ids, platoons, indices, roles, x.copy(), y.copy(), yaw.copy(), front_x.copy(),
        front_y.copy(), kin[:, SPEED].copy(), kin[:, ACCEL].copy(), lengths.copy(),
        route_s.copy(), kin[:, LATERAL].copy(), np.array(widths, dtype=np.float64), commands,
        executed, supervisor, signals, aheads, predecessors, gaps, rays, sensors,
    )  # fmt: skip


def _fixed_columns(
    members: Sequence[Member],
) -> tuple[tuple[str, ...], tuple[str, ...], tuple[int, ...], tuple[str, ...], FloatArray]:
    """The columns that stay the same while the same members drive: ids, platoons,
    places in them, roles and lengths [m]."""
    return (
        tuple(m.id for m in members), tuple(m.platoon_id for m in members),
        tuple(m.index for m in members), tuple(m.plan.role for m in members),
        np.array([m.platoon.config.vehicle.length_m for m in members], dtype=np.float64),
    )  # fmt: skip


@dataclass(frozen=True)
class StepRecord:
    """What happened in one step; handed to every hook."""

    time_s: float
    world: WorldSnapshot
    """Vehicles near the platoons (all platoon vehicles included) after the step."""
    footprints: FloatArray
    """Rectangles of `world`'s vehicles, ours from our exact state."""
    sensed_world: WorldSnapshot | None
    """The world this step's sensors observed (read after the previous SUMO step)."""
    sensed_footprints: FloatArray | None
    columns: VehicleColumns
    """The platoon vehicles after the step, as columns."""
    events: tuple[Event, ...]
    sumo_vehicles: int
    """Vehicles in the whole network after the step (platoon vehicles included)."""

    @cached_property
    def vehicles(self) -> tuple[VehicleRecord, ...]:
        """The platoon vehicles after the step, a record each (built when first asked
        for, from `columns`)."""
        return self.columns.records()

    def of_kind(self, *kinds: EventKind) -> list[Event]:
        return [e for e in self.events if e.kind in kinds]


@dataclass(frozen=True)
class RunOutcome:
    """How the run ended: `complete`, `failed` (with the error) or `interrupted`."""

    status: str
    time_s: float
    error: str = ""


class StepHook(Protocol):
    """Watches a run (recorders, progress, metrics). Subclass it and override what you
    need (the others do nothing), or write the three methods yourself."""

    def on_start(self, run: RunContext) -> None:
        """Before the first step."""
        return None

    def on_step(self, record: StepRecord) -> None:
        """After every step."""
        return None

    def on_end(self, outcome: RunOutcome) -> None:
        """After the last step, also when the run failed or was interrupted."""
        return None
