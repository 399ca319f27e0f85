"""What a controller sees and returns, the protocol it implements and the registry.

Controllers are pure decision makers: they get an Observation each step and return a
Command. They never call SUMO (the loop reads the world once and hands them a view).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, overload, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.errors import PluginError
from platoon_sumo.path import RoutePath
from platoon_sumo.registry import Registry
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import LaneChangeAhead, LinkAhead, SignalAhead, VehicleAhead


@dataclass(frozen=True)
class Observation:
    """One vehicle's view of the world at one step.

    Pose is the vehicle model's reference point (rear axle for cars, wheel axle for
    robots); `front_offset_m` is the distance from it to the front bumper along the heading.
    """

    time_s: float
    dt_s: float
    vehicle_id: str
    role: str
    x_m: float
    y_m: float
    yaw_rad: float
    speed_mps: float
    front_offset_m: float
    length_m: float
    width_m: float
    limits: MotionLimits
    path: RoutePath
    lane_offset_m: float = 0.0
    """Lateral offset (left +) of the lane the vehicle drives in from `path`: 0 when the
    controller steers along the path; with `actuation: lane` SUMO picks the lane among
    those that continue the route, so it may lie a lane or two beside the path."""
    on_sumo_lanes: bool = False
    """SUMO moves the vehicle along its lanes (`actuation: lane` and `sublane`): through a
    junction it follows the internal lane, across a lane jog too (front on the lane, back
    on the lane before). False: the controller steers the vehicle model along `path`
    everywhere (`planar`)."""
    signal: SignalAhead | None = None
    link_ahead: LinkAhead | None = None
    """The junction link at the end of the current lane with SUMO's right-of-way view,
    when that end is within reach. May be None for a controller class that declares
    `reads_link_ahead = False` on a vehicle SUMO drives: SUMO's link query, a walk over
    every link left on the route, is then made only where the loop itself needs it."""
    lane_change: LaneChangeAhead | None = None
    """The next lane change of the route within reach, and whether its target lane is clear."""
    vehicle_ahead: VehicleAhead | None = None
    """Nearest vehicle ahead on the route lanes (the traffic picture a car's ADAS has);
    laser-only followers ignore it and use `scan`."""
    obstacle_ahead: VehicleAhead | None = None
    """Nearest other vehicle whose footprint reaches into the corridor the vehicle is
    about to drive through, on any lane (a car waiting in a junction with its corner in
    this lane, a car crossing), SUMO's leader left out; its speed along the corridor."""
    scan: LaserScan | None = None
    """The latest scan of the vehicle's laser (`sensors["laser"]`), or None."""
    sensors: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    """The latest message of each of the vehicle's sensors, by the name the scenario
    gives it (the laser is "laser"); a sensor that has not produced one is absent."""
    platoon_id: str = ""
    """The vehicle's platoon (for matching V2V messages: a follower's predecessor is
    member `index - 1` of the same platoon)."""
    index: int = 0
    """Position in the platoon, 0 = leader."""


@dataclass(frozen=True)
class GapPolicy:
    """A follower's spacing policy as data: desired bumper-to-rear gap
    `standstill_m + time_gap_s * speed` (constant distance: `time_gap_s = 0`)."""

    standstill_m: float
    time_gap_s: float = 0.0

    def desired_m(self, speed_mps: float) -> float:
        return self.standstill_m + self.time_gap_s * max(speed_mps, 0.0)


@dataclass(frozen=True)
class Telemetry:
    """What a controller reports about its decision, for the trajectory table (never read
    back by the loop): its mode, the gap its perception measured when it chose the command
    (own front bumper at the start of the step to the predecessor's rear), and its
    spacing policy."""

    mode: str = ""
    measured_gap_m: float | None = None
    gap_policy: GapPolicy | None = None
    desired_accel_mps2: float | None = None
    """The acceleration the controller asks for (a CACC's input `u`); what a V2V
    channel broadcasts as the vehicle's desired acceleration. Default: derived from the
    commanded speed."""


@dataclass(frozen=True)
class Command:
    """Speed and heading command. `heading_rad`, when given, overrides `yaw_rate_radps`."""

    speed_mps: float
    yaw_rate_radps: float = 0.0
    heading_rad: float | None = None
    lane_change: int = 0
    """With `actuation: lane` (where SUMO steers): ask SUMO to move to the next lane to
    the left (+1) or right (-1); SUMO makes the change when its gap is safe. Planar
    actuation steers with the yaw rate / heading instead and ignores this."""
    telemetry: Telemetry | None = None
    """Optional report for the trajectory table (mode, measured gap, spacing policy)."""
    keep_lane: bool = False
    """With `actuation: lane`: stay in the current lane this step, a request SUMO's own
    strategic lane change does not override (a follower whose predecessor drives in
    its lane keeps it, so SUMO's strategy does not split the platoon). Ignored with a
    `lane_change` and by the other actuations."""


@dataclass(frozen=True)
class SumoCarFollowing:
    """A controller's request that SUMO's own car-following model drive the member's
    speed: the model and the vehicle-type attributes it needs. The member gets a type of
    its own with them, and its speed is handed back to SUMO every step (the command is
    then only what the supervisor checks, never sent)."""

    model: str
    """SUMO's `carFollowModel` (Krauss, IDM, ACC, CACC, ...)."""
    tau_s: float
    """The type's `tau` [s]."""
    min_gap_m: float | None
    """The type's `minGap` [m]; None: the platoon vehicle's."""
    attributes: Mapping[str, str] = dataclasses.field(default_factory=dict)
    """Further vType attributes of the model, by SUMO's names."""


def sumo_car_following(cls: type, params: Any) -> SumoCarFollowing | None:
    """What a controller class asks of SUMO's car following (its optional
    `sumo_car_following(params)`), or None: the controller commands the speed itself."""
    hook = getattr(cls, "sumo_car_following", None)
    return hook(params) if callable(hook) else None


@runtime_checkable
class Controller(Protocol):
    """A platoon vehicle's brain. `Params` is a frozen dataclass loaded from the scenario."""

    Params: ClassVar[type[Any]]

    def __init__(self, params: Any) -> None: ...

    def reset(self) -> None:
        """Forget all state (called once before the vehicle's first step)."""

    def step(self, observation: Observation) -> Command:
        """Decide this step's command; must be deterministic given the observations."""
        ...


def reads_link_ahead(cls: type) -> bool:
    """Whether a controller class may read `Observation.link_ahead`: unless the class
    itself says `reads_link_ahead = False` (the built-in controllers, which never do).
    Not inherited: a plug-in subclassing a built-in controller gets the link unless it
    says so too."""
    return bool(vars(cls).get("reads_link_ahead", True))


def check_controller(cls: object) -> str | None:
    """Why `cls` cannot be a controller (None when it can)."""
    params = getattr(cls, "Params", None)
    if (
        isinstance(params, type)
        and dataclasses.is_dataclass(params)
        and callable(getattr(cls, "reset", None))
        and callable(getattr(cls, "step", None))
    ):
        return None
    return "needs a Params dataclass, reset() and step()"


CONTROLLERS: Registry[type[Controller]] = Registry("controller", check_controller)


@dataclass(frozen=True)
class ObservationColumns:
    """The fields of many vehicles' observations at one step that a controller class
    reading columns needs, under `Observation`'s names: one array entry (or list item)
    per vehicle."""

    time_s: NDArray[np.float64]
    dt_s: NDArray[np.float64]
    x_m: NDArray[np.float64]
    y_m: NDArray[np.float64]
    yaw_rad: NDArray[np.float64]
    speed_mps: NDArray[np.float64]
    lane_offset_m: NDArray[np.float64]
    front_offset_m: NDArray[np.float64]
    length_m: NDArray[np.float64]
    width_m: NDArray[np.float64]
    limits: Sequence[MotionLimits]
    path: Sequence[RoutePath]
    scan: Sequence[LaserScan | None]
    on_sumo_lanes: Sequence[bool]
    signal: Sequence[SignalAhead | None]
    vehicle_ahead: Sequence[VehicleAhead | None]
    obstacle_ahead: Sequence[VehicleAhead | None]

    @classmethod
    def of(cls, observations: Sequence[Observation]) -> ObservationColumns:
        """The columns of built observations."""

        def floats(name: str) -> NDArray[np.float64]:
            return np.array([getattr(o, name) for o in observations], dtype=np.float64)

        return cls(
            time_s=floats("time_s"), dt_s=floats("dt_s"), x_m=floats("x_m"),
            y_m=floats("y_m"), yaw_rad=floats("yaw_rad"),
            speed_mps=floats("speed_mps"), lane_offset_m=floats("lane_offset_m"),
            front_offset_m=floats("front_offset_m"), length_m=floats("length_m"),
            width_m=floats("width_m"), limits=[o.limits for o in observations],
            path=[o.path for o in observations], scan=[o.scan for o in observations],
            on_sumo_lanes=[o.on_sumo_lanes for o in observations],
            signal=[o.signal for o in observations],
            vehicle_ahead=[o.vehicle_ahead for o in observations],
            obstacle_ahead=[o.obstacle_ahead for o in observations],
        )  # fmt: skip


class ObservationRows(Sequence[Observation]):
    """Observations handed as columns (`columns`; this sequence's k-th is row
    `rows[k]`), each `Observation` built only when first asked for: a controller class
    with a ``step_many`` that reads `columns` spares the vehicles it steps from them
    the objects."""

    def __init__(
        self,
        columns: ObservationColumns,
        build: Callable[[int], Observation],
        rows: Sequence[int] | None = None,
        built: dict[int, Observation] | None = None,
    ):
        self.columns = columns
        self.rows: Sequence[int] = range(len(columns.x_m)) if rows is None else rows
        self._build = build
        self._built: dict[int, Observation] = {} if built is None else built

    def __len__(self) -> int:
        return len(self.rows)

    @overload
    def __getitem__(self, k: int) -> Observation: ...

    @overload
    def __getitem__(self, k: slice) -> list[Observation]: ...

    def __getitem__(self, k: int | slice) -> Observation | list[Observation]:
        if isinstance(k, slice):
            return [self[j] for j in range(len(self))[k]]
        row = self.rows[k]
        found = self._built.get(row)
        if found is None:
            found = self._built[row] = self._build(row)
        return found

    def subset(self, indices: Sequence[int]) -> ObservationRows:
        """The observations at `indices` (sharing those built)."""
        rows = self.rows
        return ObservationRows(self.columns, self._build, [rows[k] for k in indices], self._built)


class MemberFailure(Exception):
    """Raised by a ``step_many`` for the vehicle whose step failed: the `index` of its
    observation in the group and the exception (`step_batch` then names that vehicle)."""

    def __init__(self, index: int, cause: Exception):
        super().__init__(index, cause)
        self.index, self.cause = index, cause


def step_batch(
    controllers: Sequence[Controller], observations: Sequence[Observation]
) -> list[Command]:
    """Commands for many vehicles at once.

    Controllers of one class whose class defines ``step_many(controllers, observations)``
    are stepped together (built-in controllers work over the whole batch); any other
    controller is stepped one by one with ``step``, so plug-ins written against ``step``
    keep working."""
    commands: list[Command | None] = [None] * len(controllers)
    groups: dict[type, list[int]] = {}
    for k, controller in enumerate(controllers):
        groups.setdefault(type(controller), []).append(k)
    for cls, indices in groups.items():
        many = getattr(cls, "step_many", None)
        if many is not None:
            group: Sequence[Observation] = (
                observations.subset(indices)
                if isinstance(observations, ObservationRows)
                else [observations[k] for k in indices]
            )
            try:
                out = many([controllers[k] for k in indices], group)
            except MemberFailure as failed:
                one = [group[failed.index]]
                raise _failure(cls, one, failed.cause) from failed.cause
            except Exception as exc:
                raise _failure(cls, group, exc) from exc
            for k, command in zip(indices, out, strict=True):
                commands[k] = _checked(cls, observations, k, command)
        else:
            for k in indices:
                try:
                    command = controllers[k].step(observations[k])
                except Exception as exc:
                    raise _failure(cls, [observations[k]], exc) from exc
                commands[k] = _checked(cls, observations, k, command)
    return [c for c in commands if c is not None]


def _failure(cls: type, group: Sequence[Observation], exc: Exception) -> PluginError:
    """The error naming the vehicle (or, for a ``step_many`` group, the vehicles) stepped."""
    names = ", ".join(f"'{obs.vehicle_id}'" for obs in group[:10])
    more = f" and {len(group) - 10} more" if len(group) > 10 else ""
    whose = f"vehicle {names}" if len(group) == 1 else f"vehicles {names}{more} (one group)"
    return PluginError(
        f"controller {cls.__module__}.{cls.__qualname__} of {whose} failed at "
        f"t={group[0].time_s:.2f} s: {type(exc).__name__}: {exc}"
    )


def _checked(cls: type, observations: Sequence[Observation], k: int, command: object) -> Command:
    """`command` if it is a Command a vehicle can execute; a PluginError naming the
    controller, the vehicle (of ``observations[k]``), the time and what is wrong
    otherwise (never let SUMO drive the car on instead)."""
    if not isinstance(command, Command):
        obs = observations[k]
        raise PluginError(
            f"{_who(cls, obs)} returned {type(command).__name__} at t={obs.time_s:.2f} s, "
            "not a Command"
        )
    problem = command_problem(command)
    if problem:
        obs = observations[k]
        raise PluginError(
            f"{_who(cls, obs)} returned an invalid command at t={obs.time_s:.2f} s: {problem}"
        )
    return command


def _who(cls: type, obs: Observation) -> str:
    return f"controller {cls.__module__}.{cls.__qualname__} of vehicle '{obs.vehicle_id}'"


_INF = math.inf


def command_problem(command: Command) -> str | None:
    """What makes `command` impossible to execute, or None."""
    speed, rate = command.speed_mps, command.yaw_rate_radps
    if (  # the usual command, in one test (every command of every step passes here)
        type(speed) is float
        and 0.0 <= speed < _INF
        and type(rate) is float
        and -_INF < rate < _INF
        and command.heading_rad is None
        and command.lane_change in (-1, 0, 1)
        and type(command.keep_lane) is bool
    ):
        return None
    if not isinstance(speed, (int, float)) or not math.isfinite(speed) or speed < 0:
        return f"speed_mps={speed!r} (must be a finite number >= 0)"
    if not isinstance(rate, (int, float)) or not math.isfinite(rate):
        return f"yaw_rate_radps={rate!r} (must be a finite number)"
    heading = command.heading_rad
    finite_heading = isinstance(heading, (int, float)) and math.isfinite(heading)
    if heading is not None and not finite_heading:
        return f"heading_rad={heading!r} (must be a finite number or None)"
    if command.lane_change not in (-1, 0, 1):
        return f"lane_change={command.lane_change!r} (must be -1, 0 or +1)"
    if not isinstance(command.keep_lane, bool):
        return f"keep_lane={command.keep_lane!r} (must be True or False)"
    return None
