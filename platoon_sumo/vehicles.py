"""Vehicle models: turn speed and yaw-rate commands into the next pose, for all vehicles at once.

Controllers command a speed and a yaw rate; a model applies the vehicle's limits and
integrates the pose. Two models are registered: ``"unicycle"`` (differential drive, the
paper's robots) and ``"bicycle"`` (kinematic bicycle, cars, whose turning is bounded by a
steering angle so a car cannot spin on the spot).

Both share one update, chosen to match SUMO and to stay exact:

1. speed moves toward the command by at most ``max_accel * dt`` up / ``max_decel * dt``
   down, then is clipped to ``[0, max_speed]`` (no reversing);
2. the yaw rate command is clipped to ``max_yaw_rate`` (and, for the bicycle, to what the
   steering limit allows at the new speed);
3. the pose moves along the exact arc for constant (new speed, yaw rate) over the step.

Using the new speed over the whole step is what SUMO's default (Euler) position update
does, so a platoon vehicle's displacement agrees with the speed passed to
``setPreviousSpeed``. The arc is exact, so a constant command traces a circle of radius
v / omega with no integration drift, whatever the step length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import ClassVar, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from platoon_sumo.geometry import wrap_angle
from platoon_sumo.registry import Registry

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class MotionLimits:
    """What a vehicle can physically do; the model enforces it whatever a controller asks."""

    max_speed_mps: float
    max_accel_mps2: float
    max_decel_mps2: float
    """Braking capability (comfortable + emergency) as a positive number."""
    max_yaw_rate_radps: float
    max_steer_rad: float = 0.6
    """Bicycle only: front-wheel steering limit, in (0, pi/2)."""
    wheelbase_m: float = 2.7
    """Bicycle only: distance from the rear axle (the reference point) to the front axle."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{f.name} must be a number, got {value!r}")
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{f.name} must be finite and > 0, got {value!r}")
        if not self.max_steer_rad < math.pi / 2:
            raise ValueError(f"max_steer_rad must be in (0, pi/2), got {self.max_steer_rad!r}")

    @property
    def min_turning_radius_m(self) -> float:
        """Bicycle only: tightest circle the rear axle can drive, L / tan(max_steer)."""
        return self.wheelbase_m / math.tan(self.max_steer_rad)


@dataclass(frozen=True, eq=False)
class KinematicState:
    """Poses and speeds of n vehicles as parallel (n,) float64 arrays.

    The reference point is the rear-axle centre (bicycle) or the wheel-axle centre
    (unicycle); converting to SUMO's front bumper is the caller's job (it needs the length).
    ``eq=False`` because array fields make ``==`` ambiguous; compare fields with numpy.
    """

    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    speed_mps: FloatArray

    def __post_init__(self) -> None:
        n: int | None = None
        for f in fields(self):
            arr = np.asarray(getattr(self, f.name), dtype=np.float64)
            if arr.ndim != 1:
                raise ValueError(f"{f.name} must be a 1-D array, got shape {arr.shape}")
            if n is not None and arr.shape[0] != n:
                raise ValueError(f"{f.name} has {arr.shape[0]} entries, expected {n}")
            n = arr.shape[0]
            object.__setattr__(self, f.name, arr)

    @classmethod
    def of(
        cls, x_m: ArrayLike, y_m: ArrayLike, yaw_rad: ArrayLike, speed_mps: ArrayLike
    ) -> KinematicState:
        """Build from scalars and/or arrays (broadcast together); copies, so callers keep theirs."""
        arrays = np.broadcast_arrays(
            *(
                np.atleast_1d(np.asarray(v, dtype=np.float64))
                for v in (x_m, y_m, yaw_rad, speed_mps)
            )
        )
        x, y, yaw, v = (np.array(a, dtype=np.float64).ravel() for a in arrays)
        return cls(x, y, wrap_angle(yaw), v)

    def __len__(self) -> int:
        return int(self.x_m.shape[0])

    def take(self, indices: ArrayLike) -> KinematicState:
        """The sub-state of the given vehicles (index array or boolean mask), as copies."""
        idx = np.asarray(indices)
        if idx.dtype != np.bool_:
            idx = idx.astype(np.int64).ravel()
        return KinematicState(self.x_m[idx], self.y_m[idx], self.yaw_rad[idx], self.speed_mps[idx])


class VehicleModel(Protocol):
    """Kinematics plug-in: one step for all vehicles of a kind; stateless and vectorised."""

    name: ClassVar[str]
    default_actuator_lag_s: ClassVar[float]
    """The powertrain lag a vehicle of this kind gets unless its scenario sets
    ``vehicle.actuator_lag_s``."""
    default_actuation: ClassVar[str]
    """The actuation a platoon of this kind gets unless its scenario sets ``actuation``
    (a plug-in model without it: ``planar``, as before this attribute existed)."""

    def step(
        self,
        state: KinematicState,
        speed_cmd_mps: FloatArray,
        yaw_rate_cmd_radps: FloatArray,
        limits: MotionLimits,
        dt_s: float,
    ) -> KinematicState:
        """The state ``dt_s`` later under the commands (shape (n,) or broadcastable)."""
        ...


VEHICLE_MODELS: Registry[type[VehicleModel]] = Registry("vehicle model")


@VEHICLE_MODELS.register("unicycle")
class Unicycle:
    """Differential drive: any yaw rate up to the limit, even at standstill (turns on the spot).
    No actuator lag by default: the paper's robots reach a commanded speed as fast as their
    acceleration limits allow."""

    name: ClassVar[str] = "unicycle"
    default_actuator_lag_s: ClassVar[float] = 0.0
    #: robots in free space (the paper's world): our model moves them in the plane
    default_actuation: ClassVar[str] = "planar"

    def step(
        self,
        state: KinematicState,
        speed_cmd_mps: FloatArray,
        yaw_rate_cmd_radps: FloatArray,
        limits: MotionLimits,
        dt_s: float,
    ) -> KinematicState:
        speed, yaw_rate = _limited_commands(state, speed_cmd_mps, yaw_rate_cmd_radps, limits, dt_s)
        return integrate_arc(state, speed, yaw_rate, dt_s)


@VEHICLE_MODELS.register("bicycle")
class Bicycle:
    """Kinematic bicycle about the rear axle: yaw rate = v tan(delta) / L, |delta| <= max_steer.
    A first-order actuator lag of 0.1 s by default (Ploeg et al.'s test vehicles).

    The commanded yaw rate maps to the steering angle delta = atan(omega L / v); clipping
    delta to max_steer and mapping back is the same as clipping omega to
    v tan(max_steer) / L, which is how it is computed (no division, so at v = 0 the yaw
    rate is exactly 0: a parked car does not turn).
    """

    name: ClassVar[str] = "bicycle"
    default_actuator_lag_s: ClassVar[float] = 0.1
    #: cars on SUMO's roads: SUMO's vehicles, steered sideways by our heading
    default_actuation: ClassVar[str] = "sublane"

    def step(
        self,
        state: KinematicState,
        speed_cmd_mps: FloatArray,
        yaw_rate_cmd_radps: FloatArray,
        limits: MotionLimits,
        dt_s: float,
    ) -> KinematicState:
        speed, yaw_rate = _limited_commands(state, speed_cmd_mps, yaw_rate_cmd_radps, limits, dt_s)
        steer_bound = speed * (math.tan(limits.max_steer_rad) / limits.wheelbase_m)
        yaw_rate = np.clip(yaw_rate, -steer_bound, steer_bound)
        return integrate_arc(state, speed, yaw_rate, dt_s)


def integrate_arc(
    state: KinematicState, speed_mps: FloatArray, yaw_rate_radps: FloatArray, dt_s: float
) -> KinematicState:
    """Exact pose after ``dt_s`` at constant speed and yaw rate (an arc, or a line).

    The chord of the arc has length ``v dt sinc(omega dt / 2)`` and points along the mean
    heading ``yaw + omega dt / 2``; written this way it needs no special case (and loses
    no precision) as omega -> 0, unlike the textbook ``v / omega (sin(...) - sin(...))``.
    """
    half_turn = 0.5 * yaw_rate_radps * dt_s
    chord = speed_mps * dt_s * np.sinc(half_turn / math.pi)  # np.sinc(x) = sin(pi x) / (pi x)
    mean_yaw = state.yaw_rad + half_turn
    return KinematicState(
        x_m=state.x_m + chord * np.cos(mean_yaw),
        y_m=state.y_m + chord * np.sin(mean_yaw),
        yaw_rad=wrap_angle(state.yaw_rad + 2.0 * half_turn),
        speed_mps=np.asarray(speed_mps, dtype=np.float64),
    )


@dataclass(frozen=True)
class Powertrain:
    """How the achieved acceleration follows the commanded one: a first-order lag
    (``da/dt = (a_cmd - a) / lag_s``, Plexe's engine lag and the `tau` of Ploeg et al.'s
    vehicle model) and a jerk bound. Zero lag and no jerk bound: the commanded speed is
    reached as fast as the acceleration limits allow (the paper's robots)."""

    lag_s: float = 0.0
    max_jerk_mps3: float | None = None

    @property
    def is_ideal(self) -> bool:
        return self.lag_s <= 0.0 and self.max_jerk_mps3 is None


def powertrain_speed(
    speed_mps: FloatArray,
    accel_mps2: FloatArray,
    speed_cmd_mps: FloatArray,
    powertrain: Powertrain,
    limits: MotionLimits,
    dt_s: float,
) -> FloatArray:
    """The speed after one step of a vehicle whose acceleration was `accel_mps2` when the
    controller commanded `speed_cmd_mps`: the commanded acceleration (the speed change
    within the limits) passes the lag, exactly discretised for a command held over the
    step (``a += (1 - exp(-dt / lag)) (a_cmd - a)``), then the jerk bound; the vehicle
    model's limits then apply as for any command."""
    _check_dt(dt_s)
    wanted = np.clip(
        (speed_cmd_mps - speed_mps) / dt_s, -limits.max_decel_mps2, limits.max_accel_mps2
    )
    accel = wanted
    if powertrain.lag_s > 0.0:
        accel = accel_mps2 + (1.0 - math.exp(-dt_s / powertrain.lag_s)) * (wanted - accel_mps2)
    if powertrain.max_jerk_mps3 is not None:
        step = powertrain.max_jerk_mps3 * dt_s
        accel = np.clip(accel, accel_mps2 - step, accel_mps2 + step)
    accel = np.clip(accel, -limits.max_decel_mps2, limits.max_accel_mps2)
    return np.maximum(speed_mps + accel * dt_s, 0.0)


def heading_to_yaw_rate(
    target_yaw_rad: ArrayLike,
    current_yaw_rad: ArrayLike,
    dt_s: float,
    max_yaw_rate: float | ArrayLike,
) -> FloatArray:
    """Yaw rate that reaches ``target_yaw_rad`` in one step the short way round, or as close
    as ``max_yaw_rate`` allows; for controllers that think in headings rather than rates."""
    _check_dt(dt_s)
    error = wrap_angle(
        np.asarray(target_yaw_rad, dtype=np.float64) - np.asarray(current_yaw_rad, dtype=np.float64)
    )
    bound = np.abs(np.asarray(max_yaw_rate, dtype=np.float64))
    return np.atleast_1d(np.clip(error / dt_s, -bound, bound)).astype(np.float64)


def _limited_commands(
    state: KinematicState,
    speed_cmd_mps: ArrayLike,
    yaw_rate_cmd_radps: ArrayLike,
    limits: MotionLimits,
    dt_s: float,
) -> tuple[FloatArray, FloatArray]:
    """New speed (accel/decel/max-speed limited, never negative) and yaw rate within limits."""
    _check_dt(dt_s)
    n = len(state)
    speed_cmd = _command(speed_cmd_mps, n, "speed_cmd_mps")
    yaw_rate_cmd = _command(yaw_rate_cmd_radps, n, "yaw_rate_cmd_radps")
    change = np.clip(
        speed_cmd - state.speed_mps,
        -limits.max_decel_mps2 * dt_s,
        limits.max_accel_mps2 * dt_s,
    )
    speed = np.clip(state.speed_mps + change, 0.0, limits.max_speed_mps)
    yaw_rate = np.clip(yaw_rate_cmd, -limits.max_yaw_rate_radps, limits.max_yaw_rate_radps)
    return speed, yaw_rate


def _command(values: ArrayLike, n: int, name: str) -> FloatArray:
    arr = np.asarray(values, dtype=np.float64)
    try:
        out = np.broadcast_to(arr, (n,))
    except ValueError:
        raise ValueError(f"{name} must have shape ({n},) or be a scalar, got {arr.shape}") from None
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{name} must be finite")
    return out


def _check_dt(dt_s: float) -> None:
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ValueError(f"dt_s must be finite and > 0, got {dt_s!r}")
