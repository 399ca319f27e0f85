"""Route following: pure pursuit on the route centre-line with a preview speed profile.

The speed profile keeps under the lane speed limit, slows into curves so the lateral
acceleration stays under a bound, and stops comfortably at the stop line of a red or
yellow signal (drives on through yellow when stopping would need hard braking).
It is the car-scale leader and the fallback of followers that lost their predecessor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from platoon_sumo.config_loader import require, require_positive
from platoon_sumo.control.base import CONTROLLERS, Command, Observation
from platoon_sumo.control.rules import safe_following_speed, signal_speed_limit
from platoon_sumo.kernels.path import profile_speed_kernel
from platoon_sumo.path import RoutePath


@dataclass(frozen=True)
class RouteFollowingParams:
    lookahead_min_m: float = 4.0
    """Shortest pure-pursuit look-ahead; robots want about their own length."""
    lookahead_time_s: float = 0.8
    """Look-ahead grows with speed: lookahead = max(min, time * speed)."""
    max_lateral_accel_mps2: float = 2.0
    """Curve speed limit: v <= sqrt(a_lat / curvature)."""
    comfort_decel_mps2: float = 2.5
    """Deceleration planned for curves, speed limits and signals."""
    yellow_max_decel_mps2: float = 4.0
    """On yellow, stop only if it takes at most this deceleration; else drive through."""
    stop_margin_m: float = 1.0
    """Front bumper stops this far before the stop line."""
    cruise_speed_mps: float | None = None
    """Optional cap below the lane speed limits (the paper's leader drives 0.1 m/s)."""
    speed_limit_factor: float = 1.0
    """Share of the lane speed limit to drive at."""
    curvature_smoothing_m: float = 3.0
    """Arc length over which the path curvature is averaged for the speed profile."""
    standstill_gap_m: float = 2.5
    """Bumper-to-bumper gap kept to a stopped vehicle ahead."""
    time_gap_s: float = 1.2
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

    def __init__(self, params: RouteFollowingParams | None = None):
        self.params = params or RouteFollowingParams()
        self._s_m = 0.0
        self._path: RoutePath | None = None
        self._curve_speed_mps = np.zeros(0)

    def reset(self) -> None:
        self._s_m = 0.0
        self._path = None

    def _prepare(self, path: RoutePath) -> None:
        if path is not self._path:
            self._path = path
            kappa = path.curvature_1pm(self.params.curvature_smoothing_m)
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
        self._prepare(path)
        lookahead = max(p.lookahead_min_m, p.lookahead_time_s * obs.speed_mps)
        self._s_m = path.project(
            obs.x_m, obs.y_m, s_hint_m=self._s_m, window_m=max(20.0, 3 * lookahead)
        ).s_m
        speed = min(self._profile_speed(obs), self._signal_speed(obs), self._following_speed(obs))
        # Predict the speed the vehicle model will reach, so the arc has the right curvature.
        limits = obs.limits
        next_speed = min(
            max(speed, obs.speed_mps - limits.max_decel_mps2 * obs.dt_s),
            obs.speed_mps + limits.max_accel_mps2 * obs.dt_s,
        )
        tx, ty = path.point_at(self._s_m + lookahead)
        if obs.lane_offset_m:  # aim along the lane SUMO drives in, beside the path's own
            heading = path.heading_at(self._s_m + lookahead)
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
        """Where SUMO steers (lane actuation): +1 / -1 towards the lane the route path
        plans on this edge, early (SUMO changes lanes only once it must, and at a queue
        it may not get in any more); 0 on the planned lane, in junctions and during the
        path's own lane changes."""
        if not obs.lane_offset_m:
            return 0
        return obs.path.lane_step(self._s_m, obs.lane_offset_m, self._s_m, 0.0)

    def _profile_speed(self, obs: Observation) -> float:
        """Highest speed from which every speed limit ahead is reachable at comfort decel."""
        path, b = obs.path, self.params.comfort_decel_mps2
        v_max = float(max(obs.limits.max_speed_mps, obs.speed_mps))
        preview_m = v_max**2 / (2 * b) + 2 * obs.length_m
        i0 = int(self._s_m // path.spacing_m)
        i1 = min(len(path.xy_m), i0 + int(preview_m / path.spacing_m) + 2)
        i0 = min(max(i0, 0), i1)
        reachable = profile_speed_kernel(
            self._curve_speed_mps, i0, i1, path.spacing_m, obs.front_offset_m, b, v_max
        )
        return float(min(reachable, obs.limits.max_speed_mps))

    def _following_speed(self, obs: Observation) -> float:
        """Keep a safe distance to the vehicle ahead (braking at comfort decel suffices)."""
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
