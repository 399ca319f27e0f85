"""Per-step metric formulas: pure functions of one step's values (see docs/metrics.md).

Everything here is computed the same way online (the recorder, every step) and offline
(from a trajectory table), so a metric never depends on where it was computed.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.kernels.trail import append_points, trail_deviations

FloatArray = NDArray[np.float64]

#: Below this speed [m/s] the time gap is undefined (a standing vehicle has no time gap).
TIME_GAP_MIN_SPEED_MPS = 0.01
#: Closing speeds [m/s] at or below this give no time to collision (not closing in).
TTC_MIN_CLOSING_MPS = 1e-6


def spacing_error_m(gap_m: FloatArray, desired_gap_m: FloatArray) -> FloatArray:
    """Ground-truth gap minus the controller's desired gap [m]; positive = too far back."""
    return gap_m - desired_gap_m


def desired_gap_m(
    standstill_m: FloatArray, time_gap_s: FloatArray, speed_mps: FloatArray
) -> FloatArray:
    """A spacing policy's desired gap at the vehicles' speeds [m] (`GapPolicy.desired_m`)."""
    return standstill_m + time_gap_s * np.maximum(speed_mps, 0.0)


def time_gap_s(gap_m: FloatArray, speed_mps: FloatArray) -> FloatArray:
    """Bumper-to-bumper gap over own speed [s]: how long until the follower reaches where
    the predecessor's rear is now (a time gap; a time headway would be measured front to
    front, the predecessor's length more); no value at (near) standstill."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # masked entries
        return np.where(speed_mps > TIME_GAP_MIN_SPEED_MPS, gap_m / speed_mps, math.nan)


def time_to_collision_s(
    gap_m: FloatArray, speed_mps: FloatArray, predecessor_speed_mps: FloatArray
) -> FloatArray:
    """Gap (0 if negative) over closing speed [s] while closing in (own speed above the
    predecessor's); no value otherwise. Constant speeds assumed, speeds along the road."""
    closing = speed_mps - predecessor_speed_mps
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # masked entries
        gap = np.where(gap_m < 0.0, 0.0, gap_m)
        return np.where(closing > TTC_MIN_CLOSING_MPS, gap / closing, math.nan)


def jerk_mps3(accel_mps2: FloatArray, previous_accel_mps2: FloatArray, dt_s: float) -> FloatArray:
    """Change of acceleration over the step [m/s³]; no value on a vehicle's first step."""
    if dt_s <= 0:
        return np.full(np.shape(accel_mps2), math.nan)
    return (accel_mps2 - previous_accel_mps2) / dt_s


def l2_gain(sum_sq_out: float, sum_sq_in: float) -> float | None:
    """sqrt(sum out²) / sqrt(sum in²), the l2 gain of sampled signals; None if the input
    is zero (nothing to amplify)."""
    if sum_sq_in <= 0.0:
        return None
    return math.sqrt(sum_sq_out) / math.sqrt(sum_sq_in)


class Trails:
    """The recent paths of vehicles' front bumpers, to measure their followers against:
    each vehicle's points kept every `spacing_m` of travel (its own, given with its first
    point), at most `max_points` (the oldest go first); points a follower has passed are
    dropped by `deviation`. All trails live in one array (a slot of rows per vehicle), so
    a step's points and measurements are one kernel call each, whatever the fleet's size.
    """

    def __init__(self, max_points: int = 5000):
        self.max_points = max_points
        self._buf = np.empty((8, min(64, max_points + 1), 2))
        self._lo = np.zeros(8, dtype=np.int64)
        self._hi = np.zeros(8, dtype=np.int64)
        self._spacing = np.zeros(8)
        self._slot: dict[str, int] = {}
        self._free: list[int] = list(range(7, -1, -1))

    def __contains__(self, vehicle_id: object) -> bool:
        return vehicle_id in self._slot

    def ids(self) -> list[str]:
        return list(self._slot)

    def points(self, vehicle_id: str) -> FloatArray:
        """The vehicle's kept points (n, 2), oldest first (a copy)."""
        s = self._slot[vehicle_id]
        return self._buf[s, self._lo[s] : self._hi[s]].copy()

    def append(
        self, ids: Sequence[str], x_m: FloatArray, y_m: FloatArray, spacing_m: FloatArray
    ) -> None:
        """Record each vehicle's position if it is at least its spacing from its last
        kept point (`spacing_m` is read for vehicles new to the trails only)."""
        if not len(ids):
            return
        slots = np.array([self._slot_of(vid, s) for vid, s in zip(ids, spacing_m, strict=True)],
                         dtype=np.int64)  # fmt: skip
        rows = self._buf.shape[1]
        if rows <= self.max_points and int((self._hi - self._lo).max()) + 1 >= rows:
            self._grow()
        x, y = np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64)
        append_points(self._buf, self._lo, self._hi, self._spacing, self.max_points, slots, x, y)

    def deviation(
        self, of: Sequence[str], x_m: FloatArray, y_m: FloatArray, prune: bool = True
    ) -> FloatArray:
        """Distance [m] from each point to the trail of the vehicle `of` names where the
        point is alongside it; NaN if it is behind the trail's start or past its end, or
        the vehicle has no trail. With `prune`, drop the points before the nearest
        segment (the follower has passed them)."""
        known = [k for k, vid in enumerate(of) if vid in self._slot]
        out = np.full(len(of), math.nan)
        if known:
            slots = np.array([self._slot[of[k]] for k in known], dtype=np.int64)
            x = np.asarray(x_m, dtype=np.float64)[known]
            y = np.asarray(y_m, dtype=np.float64)[known]
            out[known] = trail_deviations(self._buf, self._lo, self._hi, slots, x, y, prune)
        return out

    def keep_last(self, n: int, vehicle_ids: Iterable[str]) -> None:
        """Drop all but the newest `n` points of these vehicles' trails."""
        slots = [self._slot[vid] for vid in vehicle_ids]
        self._lo[slots] = np.maximum(self._lo[slots], self._hi[slots] - n)

    def forget(self, vehicle_ids: Iterable[str]) -> None:
        """Drop these vehicles' trails (their slots are used again)."""
        for vid in vehicle_ids:
            s = self._slot.pop(vid)
            self._lo[s] = self._hi[s] = 0
            self._free.append(s)

    def _slot_of(self, vehicle_id: str, spacing_m: float) -> int:
        s = self._slot.get(vehicle_id)
        if s is None:
            if not self._free:
                n = len(self._lo)
                self._buf = np.concatenate([self._buf, np.empty_like(self._buf)])
                self._lo, self._hi, self._spacing = (
                    np.concatenate([a, np.zeros_like(a)])
                    for a in (self._lo, self._hi, self._spacing)
                )
                self._free = list(range(2 * n - 1, n - 1, -1))
            s = self._slot[vehicle_id] = self._free.pop()
            self._spacing[s] = spacing_m
        return s

    def _grow(self) -> None:
        """Twice the rows a slot (up to `max_points` + 1), each trail moved to its start."""
        rows = min(2 * self._buf.shape[1], self.max_points + 1)
        buf = np.empty((len(self._lo), rows, 2))
        for s in range(len(self._lo)):
            n = self._hi[s] - self._lo[s]
            buf[s, :n] = self._buf[s, self._lo[s] : self._hi[s]]
        self._buf, self._hi, self._lo = buf, self._hi - self._lo, np.zeros_like(self._lo)
