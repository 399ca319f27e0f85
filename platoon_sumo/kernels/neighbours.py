"""Which candidate points lie within a radius of any of a set of centres."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def within_radius(centres: np.ndarray, points: np.ndarray, radius: float) -> np.ndarray:
    """Boolean mask over ``points`` (m, 2): within ``radius`` (inclusive) of at least one
    of ``centres`` (n, 2). The centres are sorted by x once and each point only checks
    those whose x lies within the radius of its own, so the cost follows the neighbours,
    not n * m."""
    order = np.argsort(centres[:, 0])
    cx = centres[order, 0]
    cy = centres[order, 1]
    r2 = radius * radius
    out = np.zeros(points.shape[0], dtype=np.bool_)
    for i in range(points.shape[0]):
        px = points[i, 0]
        py = points[i, 1]
        k = np.searchsorted(cx, px - radius)
        while k < cx.shape[0] and cx[k] <= px + radius:
            dx = cx[k] - px
            dy = cy[k] - py
            if dx * dx + dy * dy <= r2:
                out[i] = True
                break
            k += 1
    return out
