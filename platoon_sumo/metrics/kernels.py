"""Per-step metric formulas: pure functions of one step's values (see docs/metrics.md).

Everything here is computed the same way online (the recorder, every step) and offline
(from a trajectory table), so a metric never depends on where it was computed.
"""

from __future__ import annotations

import math

import numpy as np

from platoon_sumo.kernels.trail import trail_deviation

#: Below this speed [m/s] the time gap is undefined (a standing vehicle has no time gap).
TIME_GAP_MIN_SPEED_MPS = 0.01
#: Closing speeds [m/s] at or below this give no time to collision (not closing in).
TTC_MIN_CLOSING_MPS = 1e-6


def spacing_error_m(gap_m: float | None, desired_gap_m: float | None) -> float | None:
    """Ground-truth gap minus the controller's desired gap [m]; positive = too far back."""
    if gap_m is None or desired_gap_m is None:
        return None
    return gap_m - desired_gap_m


def time_gap_s(gap_m: float | None, speed_mps: float) -> float | None:
    """Bumper-to-bumper gap over own speed [s]: how long until the follower reaches where
    the predecessor's rear is now (a time gap; a time headway would be measured front to
    front, the predecessor's length more); None at (near) standstill."""
    if gap_m is None or speed_mps <= TIME_GAP_MIN_SPEED_MPS:
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

    Points are kept every `spacing_m` of travel, at most `max_points` of them (the
    oldest go first); points the follower has passed are dropped by `deviation`. The
    points live in one array (rows `lo:hi`), compacted when its end is reached.
    """

    def __init__(self, spacing_m: float, max_points: int = 5000):
        self.spacing_m = spacing_m
        self.max_points = max_points
        self._buf = np.empty((min(2 * max_points, 64), 2))
        self._lo = self._hi = 0

    def __len__(self) -> int:
        return self._hi - self._lo

    def append(self, x_m: float, y_m: float) -> None:
        """Record a position if it is at least `spacing_m` from the last kept point."""
        lo, hi, buf = self._lo, self._hi, self._buf
        if hi > lo and math.hypot(x_m - buf[hi - 1, 0], y_m - buf[hi - 1, 1]) < self.spacing_m:
            return
        if hi - lo == self.max_points:
            lo = self._lo = lo + 1
        if hi == len(buf):
            n = hi - lo
            if 2 * n > len(buf):  # more than half full: grow (up to twice max_points)
                self._buf = buf = np.concatenate([buf[lo:hi], np.empty((len(buf), 2))])
            else:
                buf[:n] = buf[lo:hi]
            self._lo, hi = 0, n
        buf[hi] = x_m, y_m
        self._hi = hi + 1

    def keep_last(self, n: int) -> None:
        """Drop all but the newest `n` points."""
        self._lo = max(self._lo, self._hi - n)

    def deviation(self, x_m: float, y_m: float, prune: bool = True) -> float | None:
        """Distance [m] from (x, y) to the trail where the point is alongside it; None if
        it is behind the trail's start or past its end. With `prune`, drop the points
        before the nearest segment (the follower has passed them)."""
        if self._hi - self._lo < 2:
            return None
        j, d = trail_deviation(self._buf[self._lo : self._hi], x_m, y_m)
        if j < 0:
            return None
        if prune:
            self._lo += j
        return d
