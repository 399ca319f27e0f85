"""Route following: pure pursuit on the route centre-line with a preview speed profile.

The speed profile keeps under the lane speed limit, slows into curves so the lateral
acceleration stays under a bound, and stops comfortably at the stop line of a red or
yellow signal (drives on through yellow when stopping would need hard braking).
It is the car-scale leader and the fallback of followers that lost their predecessor.

A step is one compiled kernel call (``platoon_sumo.kernels.route.route_step_kernel``:
projection, speed profile, pure pursuit, lane request) after the signal and
vehicle-ahead limits; what is per path (the curve speed limits, the path's arrays) and
per vehicle limits (the kernel's parameter array) is computed once. Many vehicles step
in one call (``step_many``: ``route_batch_kernel`` over their paths' stacked arrays).
The Python step it replaced is the test oracle
(``tests/control/reference_route_following.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from platoon_sumo.config_loader import bounded, require, require_positive
from platoon_sumo.control.base import (
    CONTROLLERS,
    Command,
    MemberFailure,
    Observation,
    ObservationColumns,
    ObservationRows,
)
from platoon_sumo.control.follower_rows import PathTables
from platoon_sumo.control.rules import safe_following_speed, signal_speed_limit
from platoon_sumo.frozen import frozen_from_dict
from platoon_sumo.kernels.route import (
    STEP_LANE_UNREAD,
    STEP_NOT_FINITE,
    STEP_OK,
    route_batch_kernel,
    route_step_kernel,
)
from platoon_sumo.path import RoutePath
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import SignalAhead, VehicleAhead


@dataclass(frozen=True)
class RouteFollowingParams:
    lookahead_min_m: float = bounded(4.0, gt=0, le=1000)
    """Shortest pure-pursuit look-ahead; robots want about their own length."""
    lookahead_time_s: float = bounded(0.8, gt=0, le=100)
    """Look-ahead grows with speed: lookahead = max(min, time * speed)."""
    max_lateral_accel_mps2: float = bounded(2.0, gt=0, le=50)
    """Curve speed limit: v <= sqrt(a_lat / curvature)."""
    comfort_decel_mps2: float = bounded(2.5, gt=0, le=50)
    """Deceleration planned for curves, speed limits and signals."""
    yellow_max_decel_mps2: float = bounded(4.0, gt=0, le=50)
    """On yellow, stop only if it takes at most this deceleration; else drive through."""
    stop_margin_m: float = bounded(1.0, ge=0, le=100)
    """Front bumper stops this far before the stop line."""
    cruise_speed_mps: float | None = bounded(None, gt=0, le=150)
    """Optional cap below the lane speed limits (the paper's leader drives 0.1 m/s)."""
    speed_limit_factor: float = bounded(1.0, gt=0, le=2)
    """Share of the lane speed limit to drive at."""
    curvature_smoothing_m: float = bounded(3.0, gt=0, le=1000)
    """Arc length over which the path curvature is averaged for the speed profile."""
    standstill_gap_m: float = bounded(2.5, ge=0, le=1000)
    """Bumper-to-bumper gap kept to a stopped vehicle ahead."""
    time_gap_s: float = bounded(1.2, ge=0, le=100)
    """Reaction time of the car-following term (Krauss-style safe speed)."""

    def __post_init__(self) -> None:
        require_positive(
            self, "lookahead_min_m", "lookahead_time_s", "max_lateral_accel_mps2",
            "comfort_decel_mps2", "yellow_max_decel_mps2", "curvature_smoothing_m",
        )  # fmt: skip
        require_positive(self, "stop_margin_m", "standstill_gap_m", "time_gap_s", allow_zero=True)
        require(0 < self.speed_limit_factor <= 2, "speed_limit_factor", "must be in (0, 2]")
        require(
            self.cruise_speed_mps is None or self.cruise_speed_mps > 0,
            "cruise_speed_mps",
            "must be > 0",
        )


@CONTROLLERS.register("route_following")
class RouteFollowing:
    """Pure pursuit + speed profile along the vehicle's own route."""

    Params: ClassVar[type[RouteFollowingParams]] = RouteFollowingParams
    reads_link_ahead: ClassVar[bool] = False

    def __init__(self, params: RouteFollowingParams | None = None):
        self.params = params or RouteFollowingParams()
        p = self.params
        self._s_m = 0.0
        self._path: RoutePath | None = None
        self._curve_key: tuple[bool, MotionLimits | None, float] = (False, None, 0.0)
        self._curve_speed_mps = np.zeros(0)
        self._curve_nan = False
        self._path_arrays: tuple[np.ndarray, ...] = ()
        self._batch_key: tuple[RoutePath, np.ndarray] | None = None
        """The path and curve speeds `step_many` finds in its tables."""
        self._limits: MotionLimits | None = None
        self._kernel_params = np.zeros(6)
        self._signal_args = (p.comfort_decel_mps2, p.yellow_max_decel_mps2, p.stop_margin_m)
        self._ahead_args = (p.standstill_gap_m, p.comfort_decel_mps2, p.time_gap_s)

    def reset(self) -> None:
        self._s_m = 0.0
        self._path = None

    def _prepare(
        self, path: RoutePath, on_sumo_lanes: bool, limits: MotionLimits, width_m: float
    ) -> None:
        """The path's curve speed limits. Where SUMO moves the vehicle along its lanes
        (``Observation.on_sumo_lanes``), a lane jog of a straight-through connection
        (``StraightCrossing.is_jog``: sideways out of the lane's room within less advance
        than the vehicle's tightest turn needs) adds none: no car drives it as a bend;
        SUMO moves its cars across at the lane's speed, their bodies swung across it
        (front on the lane, back on the lane before), and a car crawling through at the
        bend's curve speed stays swung across the lane beside for seconds (eclipse-sumo's
        `highway` network: a motorway lane jogs 4.8 m sideways within 0.3 m)."""
        key = (on_sumo_lanes, limits if on_sumo_lanes else None, width_m)
        if path is not self._path or key != self._curve_key:
            self._path, self._curve_key = path, key
            left_out: frozenset[str] = frozenset()
            if on_sumo_lanes and path.straight_crossings:
                radius = limits.wheelbase_m / math.tan(limits.max_steer_rad)  # tightest turn
                left_out = path.jog_lanes(radius, width_m)
            kappa = path.curvature_1pm(self.params.curvature_smoothing_m, left_out)
            curve = np.sqrt(self.params.max_lateral_accel_mps2 / np.maximum(kappa, 1e-9))
            limit = path.speed_limit_mps * self.params.speed_limit_factor
            self._curve_speed_mps = np.minimum(curve, limit)
            if self.params.cruise_speed_mps is not None:
                self._curve_speed_mps = np.minimum(
                    self._curve_speed_mps, self.params.cruise_speed_mps
                )
            self._curve_speed_mps = np.ascontiguousarray(self._curve_speed_mps, dtype=np.float64)
            self._curve_nan = bool(np.isnan(self._curve_speed_mps).any())
            self._path_arrays = path.kernel_arrays
            self._batch_key = (path, self._curve_speed_mps)  # a new entry of the tables

    def step(self, observation: Observation) -> Command:
        return self._step(
            observation,
            self._ahead_limit(observation.vehicle_ahead, observation.obstacle_ahead),
        )

    def _ahead_limit(
        self, vehicle_ahead: VehicleAhead | None, obstacle_ahead: VehicleAhead | None
    ) -> float:
        """The safe speed behind SUMO's leader and the nearest obstacle (inf: none)."""
        limit = math.inf
        for ahead in (vehicle_ahead, obstacle_ahead):
            if ahead is not None:
                gap, speed = ahead.gap_m, ahead.speed_mps
                limit = min(limit, safe_following_speed(gap, speed, *self._ahead_args))
        return limit

    def _signal_limit(self, signal: SignalAhead | None, speed_mps: float, dt_s: float) -> float:
        """The speed that stops at a red or yellow light ahead in time (inf: none)."""
        return signal_speed_limit(signal, speed_mps, dt_s, *self._signal_args)

    @staticmethod
    def step_many(
        controllers: Sequence[RouteFollowing], observations: Sequence[Observation]
    ) -> list[Command]:
        """``step`` for many vehicles: their kernel steps in one call
        (``route_batch_kernel``) on their paths and curve speeds stacked in tables, from
        the observations' columns (handed `ObservationRows`, no `Observation` is built).
        A subclass that overrides ``step`` or ``_step`` is stepped with it."""
        if isinstance(observations, ObservationRows):
            cols, at = observations.columns, observations.rows
        else:
            cols, at = ObservationColumns.of(observations), range(len(observations))
        commands: list[Command | None] = [None] * len(controllers)
        batch: list[int] = []
        for k, c in enumerate(controllers):
            if type(c).step is RouteFollowing.step and type(c)._step is RouteFollowing._step:
                batch.append(k)
                continue
            try:
                commands[k] = c.step(observations[k])
            except Exception as exc:
                raise MemberFailure(k, exc) from exc
        if batch:
            rows = [at[k] for k in batch]
            _step_together([controllers[k] for k in batch], cols, rows, batch, commands)
        return [c for c in commands if c is not None]

    def _step(self, obs: Observation, ahead_limit_mps: float) -> Command:
        """``step`` with the vehicle-ahead speed limit given (inf: none; the laser
        follower's fallback steps blind to SUMO's leader)."""
        path = obs.path
        if path is not self._path or obs.on_sumo_lanes != self._curve_key[0]:
            self._prepare(path, obs.on_sumo_lanes, obs.limits, obs.width_m)
        if obs.limits is not self._limits:
            self._set_limits(obs.limits)
        signal_limit = self._signal_limit(obs.signal, obs.speed_mps, obs.dt_s)
        xy, blocks, widths, codes, spans, geometry = self._path_arrays
        status, s, speed, yaw_rate, lane = route_step_kernel(
            xy, blocks, widths, codes, spans, geometry, self._curve_speed_mps, self._curve_nan,
            self._kernel_params, self._s_m, obs.x_m, obs.y_m, obs.yaw_rad, obs.speed_mps,
            obs.front_offset_m, obs.length_m, obs.dt_s, obs.lane_offset_m, signal_limit,
            ahead_limit_mps,
        )  # fmt: skip
        return self._command(
            int(status), s, speed, yaw_rate, int(lane), path, obs.x_m, obs.y_m,
            obs.speed_mps, obs.length_m, obs.lane_offset_m, obs.limits,
        )  # fmt: skip

    def _command(
        self, status: int, s: float, speed: float, yaw_rate: float, lane: int, path: RoutePath,
        x_m: float, y_m: float, speed_mps: float, length_m: float, lane_offset_m: float,
        limits: MotionLimits,
    ) -> Command:  # fmt: skip
        """The command from a kernel step's (status, arc length, speed, yaw rate, lane
        request); the arc length kept for the next step's projection."""
        if status == STEP_NOT_FINITE:
            raise ValueError(
                f"route following cannot step from a non-finite state: x={x_m} "
                f"y={y_m} speed={speed_mps} length={length_m} "
                f"lane offset={lane_offset_m} "
                f"max speed={limits.max_speed_mps} (arc length {self._s_m})"
            )
        self._s_m = s
        if status == STEP_LANE_UNREAD:  # lane ids that do not read as EDGE_INDEX
            lane = path.lane_step(s, lane_offset_m, s, 0.0)
        return _route_command(speed, yaw_rate, lane)

    def _set_limits(self, limits: MotionLimits) -> None:
        """The kernel's parameters (``PARAM_NAMES``) with these limits."""
        p = self.params
        self._kernel_params = np.array(
            [
                p.lookahead_min_m, p.lookahead_time_s, p.comfort_decel_mps2,
                limits.max_speed_mps, limits.max_decel_mps2, limits.max_accel_mps2,
            ],
            dtype=np.float64,
        )  # fmt: skip
        self._limits = limits


def _route_command(speed_mps: float, yaw_rate_radps: float, lane_change: int) -> Command:
    """A route-following step's command (no heading, telemetry or lane hold)."""
    return frozen_from_dict(Command, {
        "speed_mps": speed_mps, "yaw_rate_radps": yaw_rate_radps, "heading_rad": None,
        "lane_change": lane_change, "telemetry": None, "keep_lane": False,
    })  # fmt: skip


_TABLE_NAMES = ("xy", "blocks", "widths", "codes", "spans", "curve", "geometry")
_TABLES = PathTables(_TABLE_NAMES)
"""The paths and curve speeds of the vehicles `RouteFollowing.step_many` steps."""


def _table_rows(key: object) -> tuple[np.ndarray, ...]:
    assert isinstance(key, tuple)
    path, curve = key
    xy, blocks, widths, codes, spans, geometry = path.kernel_arrays
    flags = np.array([*geometry, float(np.isnan(curve).any())], dtype=np.float64)
    return xy, blocks, widths, codes, spans, curve, flags[None, :]


def _step_together(
    controllers: list[RouteFollowing],
    cols: ObservationColumns,
    rows: list[int],
    index: list[int],
    commands: list[Command | None],
) -> None:
    """The steps of `controllers` (their observations rows `rows` of `cols`; their
    places `index` in `commands`) in one kernel call."""
    path, limits, signal = cols.path, cols.limits, cols.signal
    on_lanes, width = cols.on_sumo_lanes, cols.width_m.tolist()
    vehicle_ahead, obstacle_ahead = cols.vehicle_ahead, cols.obstacle_ahead
    speed, dt = cols.speed_mps.tolist(), cols.dt_s.tolist()
    keys: list[object] = []
    hints, params, signal_limits, ahead_limits = [], [], [], []
    for j, (c, r) in enumerate(zip(controllers, rows, strict=True)):
        try:
            p, lim = path[r], limits[r]
            if p is not c._path or on_lanes[r] != c._curve_key[0]:
                c._prepare(p, on_lanes[r], lim, width[r])
            if lim is not c._limits:
                c._set_limits(lim)
            stop = signal[r]
            signal_limits.append(
                math.inf if stop is None else c._signal_limit(stop, speed[r], dt[r])
            )
            a, b = vehicle_ahead[r], obstacle_ahead[r]
            ahead_limits.append(math.inf if a is None and b is None else c._ahead_limit(a, b))
        except Exception as exc:
            raise MemberFailure(index[j], exc) from exc
        keys.append(c._batch_key)
        hints.append(c._s_m)
        params.append(c._kernel_params)
    at = np.array(rows, dtype=np.int64)
    inputs = np.column_stack([
        np.array(hints, dtype=np.float64), cols.x_m[at], cols.y_m[at], cols.yaw_rad[at],
        cols.speed_mps[at], cols.front_offset_m[at], cols.length_m[at], cols.dt_s[at],
        cols.lane_offset_m[at], np.array(signal_limits, dtype=np.float64),
        np.array(ahead_limits, dtype=np.float64), np.array(params, dtype=np.float64),
    ])  # fmt: skip
    tables = _TABLES
    entry = np.array(tables.numbers(keys, _table_rows), dtype=np.int64)
    table, starts = tables.table, tables.starts
    out = route_batch_kernel(
        table("xy"), starts("xy"), table("blocks"), starts("blocks"), table("widths"),
        table("codes"), starts("codes"), table("spans"), starts("spans"), table("curve"),
        starts("curve"), table("geometry"), entry, inputs,
    )  # fmt: skip
    x, y, length, offset = cols.x_m, cols.y_m, cols.length_m, cols.lane_offset_m
    for j, (c, r, values) in enumerate(zip(controllers, rows, out.tolist(), strict=True)):
        status, s, cmd_speed, yaw_rate, lane = values
        if status == STEP_OK:  # `_command` without its checks
            c._s_m = s
            commands[index[j]] = _route_command(cmd_speed, yaw_rate, int(lane))
            continue
        try:
            commands[index[j]] = c._command(
                int(status), s, cmd_speed, yaw_rate, int(lane), path[r], float(x[r]),
                float(y[r]), speed[r], float(length[r]), float(offset[r]), limits[r],
            )  # fmt: skip
        except Exception as exc:
            raise MemberFailure(index[j], exc) from exc
