"""Per-step metric formulas: pure functions of one step's values (see docs/metrics.md).

Everything here is computed the same way online (the recorder, every step) and offline
(from a trajectory table), so a metric never depends on where it was computed.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

#: Below this speed [m/s] the time headway is undefined (a standing vehicle has no headway).
HEADWAY_MIN_SPEED_MPS = 0.01
#: Closing speeds [m/s] at or below this give no time to collision (not closing in).
TTC_MIN_CLOSING_MPS = 1e-6


def spacing_error_m(gap_m: float | None, desired_gap_m: float | None) -> float | None:
    """Ground-truth gap minus the controller's desired gap [m]; positive = too far back."""
    if gap_m is None or desired_gap_m is None:
        return None
    return gap_m - desired_gap_m


def time_headway_s(gap_m: float | None, speed_mps: float) -> float | None:
    """Gap over own speed [s]: how long until the follower reaches where the predecessor's
    rear is now; None at (near) standstill."""
    if gap_m is None or speed_mps <= HEADWAY_MIN_SPEED_MPS:
        return None
    return gap_m / speed_mps


def time_to_collision_s(
    gap_m: float | None, speed_mps: float, predecessor_speed_mps: float | None
) -> float | None:
    """Gap over closing speed [s] while closing in (own speed above the predecessor's);
    None otherwise. Constant speeds assumed, speeds along the road."""
    if gap_m is None or predecessor_speed_mps is None:
        return None
    closing = speed_mps - predecessor_speed_mps
    if closing <= TTC_MIN_CLOSING_MPS:
        return None
    return max(gap_m, 0.0) / closing


def jerk_mps3(accel_mps2: float, previous_accel_mps2: float | None, dt_s: float) -> float | None:
    """Change of acceleration over the step [m/s³]; None on a vehicle's first step."""
    if previous_accel_mps2 is None or dt_s <= 0:
        return None
    return (accel_mps2 - previous_accel_mps2) / dt_s


def l2_gain(sum_sq_out: float, sum_sq_in: float) -> float | None:
    """sqrt(sum out²) / sqrt(sum in²), the l2 gain of sampled signals; None if the input
    is zero (nothing to amplify)."""
    if sum_sq_in <= 0.0:
        return None
    return math.sqrt(sum_sq_out) / math.sqrt(sum_sq_in)


class PathTrail:
    """The recent path of one vehicle's front bumper, to measure its follower against.

    Points are kept every `spacing_m` of travel, at most `max_points` of them; points the
    follower has passed are dropped by `deviation`. Memory is bounded by `max_points`.
    """

    def __init__(self, spacing_m: float, max_points: int = 5000):
        self.spacing_m = spacing_m
        self._points: deque[tuple[float, float]] = deque(maxlen=max_points)

    def __len__(self) -> int:
        return len(self._points)

    def append(self, x_m: float, y_m: float) -> None:
        """Record a position if it is at least `spacing_m` from the last kept point."""
        pts = self._points
        if not pts or math.hypot(x_m - pts[-1][0], y_m - pts[-1][1]) >= self.spacing_m:
            pts.append((x_m, y_m))

    def keep_last(self, n: int) -> None:
        """Drop all but the newest `n` points."""
        while len(self._points) > n:
            self._points.popleft()

    def deviation(self, x_m: float, y_m: float, prune: bool = True) -> float | None:
        """Distance [m] from (x, y) to the trail where the point is alongside it; None if
        it is behind the trail's start or past its end. With `prune`, drop the points
        before the nearest segment (the follower has passed them)."""
        if len(self._points) < 2:
            return None
        pts = np.asarray(self._points, dtype=np.float64)
        a, e = pts[:-1], np.diff(pts, axis=0)
        ee = np.einsum("ij,ij->i", e, e)
        w = np.array([x_m, y_m]) - a
        raw = np.divide(np.einsum("ij,ij->i", w, e), ee, out=np.zeros(len(e)), where=ee > 0)
        t = np.clip(raw, 0.0, 1.0)
        d = np.hypot(a[:, 0] + t * e[:, 0] - x_m, a[:, 1] + t * e[:, 1] - y_m)
        j = int(np.argmin(d))
        if (j == 0 and raw[0] <= 1e-9) or (j == len(e) - 1 and raw[-1] >= 1.0 - 1e-9):
            return None
        if prune:
            for _ in range(j):
                self._points.popleft()
        return float(d[j])
