"""Metric kernels: the predecessors' trails and how far a follower's front bumper is from
its predecessor's (``metrics.kernels.Trails`` keeps them)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def trail_deviation(pts: np.ndarray, x: float, y: float) -> tuple[int, float]:
    """Nearest segment of the polyline ``pts`` (n >= 2, (n, 2)) to (x, y): (its index,
    the distance [m]), or (-1, nan) when the point is behind the first vertex or past
    the last one (the nearest point is an end and the projection falls outside). The
    first of equally near segments wins, as ``np.argmin`` has it."""
    n_seg = pts.shape[0] - 1
    best = np.inf
    best_k = 0
    first_raw = 0.0
    last_raw = 0.0
    for k in range(n_seg):
        ax = pts[k, 0]
        ay = pts[k, 1]
        ex = pts[k + 1, 0] - ax
        ey = pts[k + 1, 1] - ay
        ee = ex * ex + ey * ey
        raw = ((x - ax) * ex + (y - ay) * ey) / ee if ee > 0.0 else 0.0
        t = min(max(raw, 0.0), 1.0)
        d = math.hypot(ax + t * ex - x, ay + t * ey - y)
        if k == 0:
            first_raw = raw
        if k == n_seg - 1:
            last_raw = raw
        if d < best or (d != d and best == best):
            best = d
            best_k = k
    if (best_k == 0 and first_raw <= 1e-9) or (best_k == n_seg - 1 and last_raw >= 1.0 - 1e-9):
        return -1, math.nan
    return best_k, best


@njit(cache=True)
def append_points(
    buf: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    spacing: np.ndarray,
    max_points: int,
    slots: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
) -> None:
    """Append (x[k], y[k]) to the trail in ``slots[k]`` (rows ``lo:hi`` of ``buf[slot]``)
    unless it lies closer than the slot's ``spacing`` to the trail's last point; the
    oldest point goes when the trail holds ``max_points``, and a trail at the end of its
    rows is moved to their start. The caller leaves room: fewer points than rows."""
    rows = buf.shape[1]
    for k in range(slots.shape[0]):
        s = slots[k]
        a = lo[s]
        b = hi[s]
        if b > a and math.hypot(x[k] - buf[s, b - 1, 0], y[k] - buf[s, b - 1, 1]) < spacing[s]:
            continue
        if b - a == max_points:
            a += 1
        if b == rows:
            for i in range(b - a):
                buf[s, i, 0] = buf[s, a + i, 0]
                buf[s, i, 1] = buf[s, a + i, 1]
            b -= a
            a = 0
        buf[s, b, 0] = x[k]
        buf[s, b, 1] = y[k]
        lo[s] = a
        hi[s] = b + 1


@njit(cache=True)
def trail_deviations(
    buf: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    slots: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    prune: bool,
) -> np.ndarray:
    """``trail_deviation`` of (x[k], y[k]) against the trail in ``slots[k]`` (NaN: a
    trail of fewer than two points, or the point is not alongside it); with ``prune``
    the points before the nearest segment are dropped, in the order of k."""
    out = np.full(slots.shape[0], np.nan)
    for k in range(slots.shape[0]):
        s = slots[k]
        a = lo[s]
        if hi[s] - a < 2:
            continue
        j, d = trail_deviation(buf[s, a : hi[s]], x[k], y[k])
        if j < 0:
            continue
        if prune:
            lo[s] = a + j
        out[k] = d
    return out
