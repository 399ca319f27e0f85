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


@njit(cache=True)
def lanes_within(
    points: np.ndarray,
    radius: float,
    origin: np.ndarray,
    cell_m: float,
    cells_y: int,
    cell_starts: np.ndarray,
    cell_segments: np.ndarray,
    segments: np.ndarray,
    pads: np.ndarray,
    segment_lane: np.ndarray,
    lane_count: int,
) -> np.ndarray:
    """Boolean mask over lanes: some segment of the lane lies within ``radius`` plus its
    pad of one of ``points`` (n, 2). ``segments`` (m, 4) hold (ax, ay, bx, by); each is
    listed (``cell_segments[cell_starts[c]:cell_starts[c + 1]]``) in every cell of the
    row-major grid (``cells_y`` cells a column, ``origin`` the lowest corner) that its
    bounding box widened by its pad touches, so a point only visits the cells within
    ``radius`` of its own."""
    mask = np.zeros(lane_count, dtype=np.bool_)
    cells_x = (cell_starts.shape[0] - 1) // cells_y
    reach = int(np.ceil(radius / cell_m))
    for i in range(points.shape[0]):
        px = points[i, 0]
        py = points[i, 1]
        cx = int(np.floor((px - origin[0]) / cell_m))
        cy = int(np.floor((py - origin[1]) / cell_m))
        for gx in range(max(cx - reach, 0), min(cx + reach, cells_x - 1) + 1):
            for gy in range(max(cy - reach, 0), min(cy + reach, cells_y - 1) + 1):
                c = gx * cells_y + gy
                for k in range(cell_starts[c], cell_starts[c + 1]):
                    s = cell_segments[k]
                    lane = segment_lane[s]
                    if mask[lane]:
                        continue
                    ax = segments[s, 0]
                    ay = segments[s, 1]
                    dx = segments[s, 2] - ax
                    dy = segments[s, 3] - ay
                    squared = dx * dx + dy * dy
                    t = 0.0
                    if squared > 0.0:
                        t = min(max(((px - ax) * dx + (py - ay) * dy) / squared, 0.0), 1.0)
                    ex = ax + t * dx - px
                    ey = ay + t * dy - py
                    reach_m = radius + pads[s]
                    if ex * ex + ey * ey <= reach_m * reach_m:
                        mask[lane] = True
    return mask
