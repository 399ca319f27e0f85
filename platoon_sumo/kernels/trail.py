"""Metric kernel: how far a follower's front bumper is from its predecessor's trail."""

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
