"""REFERENCE ONLY (test oracle): ``platoon_sumo/control/route_following.py`` and the
``RoutePath`` look-ups it used, as they were before the route-following step became one
kernel call (``platoon_sumo.kernels.route``), kept so the equivalence tests
(``test_route_following_equivalence.py``) and ``tools/bench_controllers.py`` can replay
observations through it. Changes from the original: the path look-ups it called
(``project``, ``point_at``, ``heading_at``, ``lane_step``) are free functions here,
copied from ``platoon_sumo/path.py`` as they were (the projection and the speed-profile
look-ahead call the unchanged kernels of ``platoon_sumo.kernels.path``, themselves
tested against numpy), and it is not registered as a controller. Do not use in package
code, do not change.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from platoon_sumo.control.base import Command, Observation
from platoon_sumo.control.route_following import RouteFollowingParams
from platoon_sumo.control.rules import safe_following_speed, signal_speed_limit
from platoon_sumo.kernels.path import profile_speed_kernel, project_kernel
from platoon_sumo.path import RoutePath

# ----------------------------------------------------------------------------- path


def _last_step(path: RoutePath) -> float:
    return float(np.hypot(*(path.xy_m[-1] - path.xy_m[-2])))


def length_m(path: RoutePath) -> float:
    return float((len(path.xy_m) - 2) * path.spacing_m + _last_step(path))


def _index(path: RoutePath, s_m: float) -> int:
    return int(min(max(s_m // path.spacing_m, 0), len(path.xy_m) - 2))


def point_at(path: RoutePath, s_m: float) -> tuple[float, float]:
    s = float(min(max(s_m, 0.0), length_m(path)))
    spacing, last = path.spacing_m, len(path.xy_m) - 2
    i = int(min(s // spacing, last))
    step = spacing if i < last else _last_step(path)
    t = (s - i * spacing) / step if step > 0 else 0.0
    t = min(max(t, 0.0), 1.0)
    xy = path.xy_m
    x0, y0, x1, y1 = float(xy[i, 0]), float(xy[i, 1]), float(xy[i + 1, 0]), float(xy[i + 1, 1])
    return x0 + (x1 - x0) * t, y0 + (y1 - y0) * t


def heading_at(path: RoutePath, s_m: float) -> float:
    i = _index(path, float(min(max(s_m, 0.0), length_m(path))))
    xy = path.xy_m
    return math.atan2(float(xy[i + 1, 1] - xy[i, 1]), float(xy[i + 1, 0] - xy[i, 0]))


def _lane_key(path: RoutePath, i: int) -> tuple[str, ...] | None:
    id_ = path.lane_ids[int(path.lane_index[i])]
    return None if id_.startswith(":") else tuple(id_.rsplit("_", 1))


def lane_step(
    path: RoutePath, s_m: float, offset_m: float, target_s_m: float, target_offset_m: float
) -> int:
    for c in path.lane_changes:
        begin, end = c.begin_s_m, c.end_s_m
        if begin <= s_m <= end or begin <= target_s_m <= end:
            return 0
    spacing, last = path.spacing_m, len(path.xy_m) - 1
    widths = path.lane_width_m
    i = min(int(max(s_m, 0.0) // spacing), last)
    own = _lane_key(path, i)
    if own is None:
        return 0
    own_edge, own_index = own
    own_lane = int(own_index) + round(offset_m / float(widths[i]))
    j = min(int(max(target_s_m, 0.0) // spacing), last)
    target = _lane_key(path, j)
    if target is None:
        return 0
    target_edge, target_index = target
    target_lane = int(target_index) + round(target_offset_m / float(widths[j]))
    if own_edge != target_edge or own_lane == target_lane:
        return 0
    return 1 if target_lane > own_lane else -1


def project_s(path: RoutePath, x_m: float, y_m: float, s_hint_m: float, window_m: float) -> float:
    hint, window = float(s_hint_m), float(window_m)
    if not (math.isfinite(hint) and 0.0 <= window < math.inf):
        raise ValueError(f"project: bad hint {s_hint_m!r} or window {window_m!r}")
    xy = np.ascontiguousarray(path.xy_m, dtype=np.float64)
    widths = np.ascontiguousarray(path.lane_width_m, dtype=np.float64)
    s, _, _ = project_kernel(
        xy, widths, path.spacing_m, length_m(path), True, hint, window, float(x_m), float(y_m)
    )
    return float(s)


# ----------------------------------------------------------------------------- controller


class ReferenceRouteFollowing:
    """Pure pursuit + speed profile along the vehicle's own route."""

    Params: ClassVar[type[RouteFollowingParams]] = RouteFollowingParams

    def __init__(self, params: RouteFollowingParams | None = None):
        self.params = params or RouteFollowingParams()
        self._s_m = 0.0
        self._path: RoutePath | None = None
        self._curve_speed_mps = np.zeros(0)

    def reset(self) -> None:
        self._s_m = 0.0
        self._path = None

    def _prepare(self, path: RoutePath, obs: Observation) -> None:
        key = (obs.on_sumo_lanes, obs.limits, obs.width_m)
        if path is not self._path or key != getattr(self, "_key", None):
            self._path, self._key = path, key
            left_out: frozenset[str] = frozenset()
            if obs.on_sumo_lanes:  # lane jogs of straight-through connections: no bend
                radius = obs.limits.wheelbase_m / math.tan(obs.limits.max_steer_rad)
                left_out = path.jog_lanes(radius, obs.width_m)
            kappa = path.curvature_1pm(self.params.curvature_smoothing_m, left_out)
            curve = np.sqrt(self.params.max_lateral_accel_mps2 / np.maximum(kappa, 1e-9))
            limit = path.speed_limit_mps * self.params.speed_limit_factor
            self._curve_speed_mps = np.minimum(curve, limit)
            if self.params.cruise_speed_mps is not None:
                self._curve_speed_mps = np.minimum(
                    self._curve_speed_mps, self.params.cruise_speed_mps
                )

    def step(self, observation: Observation) -> Command:
        obs, p = observation, self.params
        path = obs.path
        self._prepare(path, obs)
        lookahead = max(p.lookahead_min_m, p.lookahead_time_s * obs.speed_mps)
        self._s_m = project_s(path, obs.x_m, obs.y_m, self._s_m, max(20.0, 3 * lookahead))
        speed = min(self._profile_speed(obs), self._signal_speed(obs), self._following_speed(obs))
        # Predict the speed the vehicle model will reach, so the arc has the right curvature.
        limits = obs.limits
        next_speed = min(
            max(speed, obs.speed_mps - limits.max_decel_mps2 * obs.dt_s),
            obs.speed_mps + limits.max_accel_mps2 * obs.dt_s,
        )
        tx, ty = point_at(path, self._s_m + lookahead)
        if obs.lane_offset_m:  # aim along the lane SUMO drives in, beside the path's own
            heading = heading_at(path, self._s_m + lookahead)
            tx -= obs.lane_offset_m * math.sin(heading)
            ty += obs.lane_offset_m * math.cos(heading)
        dx, dy = tx - obs.x_m, ty - obs.y_m
        dist = math.hypot(dx, dy)
        alpha = math.atan2(dy, dx) - obs.yaw_rad
        curvature = 2.0 * math.sin(alpha) / dist if dist > 1e-6 else 0.0
        return Command(
            speed_mps=speed,
            yaw_rate_radps=max(next_speed, 0.0) * curvature,
            lane_change=self._lane_request(obs),
        )

    def _lane_request(self, obs: Observation) -> int:
        if not obs.lane_offset_m:
            return 0
        return lane_step(obs.path, self._s_m, obs.lane_offset_m, self._s_m, 0.0)

    def _profile_speed(self, obs: Observation) -> float:
        path, b = obs.path, self.params.comfort_decel_mps2
        v_max = float(max(obs.limits.max_speed_mps, obs.speed_mps))
        preview_m = v_max**2 / (2 * b) + 2 * obs.length_m
        i0 = int(self._s_m // path.spacing_m)
        i1 = min(len(path.xy_m), i0 + int(preview_m / path.spacing_m) + 2)
        i0 = min(max(i0, 0), i1)
        curve = np.ascontiguousarray(self._curve_speed_mps, dtype=np.float64)
        reachable = profile_speed_kernel(
            curve, i0, i1, path.spacing_m, obs.front_offset_m, b, v_max
        )
        return float(min(reachable, obs.limits.max_speed_mps))

    def _following_speed(self, obs: Observation) -> float:
        ahead = obs.vehicle_ahead
        if ahead is None:
            return math.inf
        p = self.params
        return safe_following_speed(
            ahead.gap_m, ahead.speed_mps, p.standstill_gap_m, p.comfort_decel_mps2, p.time_gap_s
        )

    def _signal_speed(self, obs: Observation) -> float:
        p = self.params
        return signal_speed_limit(
            obs.signal, obs.speed_mps, obs.dt_s, p.comfort_decel_mps2, p.yellow_max_decel_mps2,
            p.stop_margin_m,
        )  # fmt: skip
