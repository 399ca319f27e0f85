"""Route-path kernels: nearest point of a polyline, searched within a window."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def window_segments(
    n_seg: int, spacing: float, use_hint: bool, s_hint: float, window: float
) -> tuple[int, int, int]:
    """(first, end, centre) segments searched: all without a hint; else those within
    ``window`` (plus one segment) of the segment at ``s_hint`` (the centre)."""
    if not use_hint:
        return 0, n_seg, 0
    w = int(window / spacing) + 1
    centre = int(min(max(s_hint // spacing, 0.0), n_seg - 1.0))
    return max(0, centre - w), min(n_seg, centre + w + 1), centre


@njit(cache=True)
def segment_d2(xy: np.ndarray, k: int, x: float, y: float) -> tuple[float, float, float]:
    """(squared distance, t of the nearest point, squared length) of segment k of the
    polyline ``xy`` to (x, y)."""
    ax = xy[k, 0]
    ay = xy[k, 1]
    dx = xy[k + 1, 0] - ax
    dy = xy[k + 1, 1] - ay
    len2 = dx * dx + dy * dy
    t = ((x - ax) * dx + (y - ay) * dy) / max(len2, 1e-18)
    t = min(max(t, 0.0), 1.0)
    cx = ax + dx * t - x
    cy = ay + dy * t - y
    return cx * cx + cy * cy, t, len2


@njit(cache=True)
def project_kernel(
    xy: np.ndarray,
    widths: np.ndarray,
    spacing: float,
    length: float,
    use_hint: bool,
    s_hint: float,
    window: float,
    x: float,
    y: float,
) -> tuple[float, float, float]:
    """Nearest point to (x, y) of the polyline ``xy`` (n, 2) whose vertex i lies at arc
    length ``i * spacing`` (the last one at ``length``): (arc length, signed lateral
    offset, left +, and ``widths`` at the vertex at or before it). With ``use_hint``, only
    the segments within ``window`` (plus one segment) of the one at ``s_hint`` are
    searched. The first of equally near segments wins."""
    lo, hi, _ = window_segments(xy.shape[0] - 1, spacing, use_hint, s_hint, window)
    best = np.inf
    best_k = lo
    best_t = 0.0
    best_len2 = 0.0
    for k in range(lo, hi):
        d2, t, len2 = segment_d2(xy, k, x, y)
        if d2 < best:
            best, best_k, best_t, best_len2 = d2, k, t, len2
        elif d2 != d2:  # NaN (a NaN point): the first one wins, as np.argmin has it
            best, best_k, best_t, best_len2 = d2, k, t, len2
            break
    return projection_at(xy, widths, spacing, length, x, y, best_k, best_t, best_len2, best)


@njit(cache=True)
def projection_at(
    xy: np.ndarray,
    widths: np.ndarray,
    spacing: float,
    length: float,
    x: float,
    y: float,
    k: int,
    t: float,
    len2: float,
    d2: float,
) -> tuple[float, float, float]:
    """(arc length, signed lateral offset, lane width) of (x, y) projected at ``t`` on
    segment ``k`` (squared length ``len2``, squared distance ``d2``): left is positive."""
    ax = xy[k, 0]
    ay = xy[k, 1]
    dx = xy[k + 1, 0] - ax
    dy = xy[k + 1, 1] - ay
    cross = dx * (y - ay) - dy * (x - ax)
    s = min(k * spacing + t * math.sqrt(len2), length)
    width = widths[min(int(s // spacing), widths.size - 1)]
    return s, math.copysign(math.sqrt(d2), cross), width


@njit(cache=True)
def profile_speed_kernel(
    curve_speed: np.ndarray,
    i0: int,
    i1: int,
    spacing: float,
    front_offset: float,
    decel: float,
    v_max: float,
) -> float:
    """Highest speed from which every speed limit ``curve_speed[i0:i1]`` (one per path
    vertex, ``spacing`` apart, the first at the reference point, ``front_offset`` behind
    the front bumper) is reachable braking at ``decel``, and at most ``v_max``."""
    best = v_max
    two_b = 2 * decel
    for k in range(i1 - i0):
        limit = curve_speed[i0 + k]
        dist = max(k * spacing - front_offset, 0.0)
        allowed = math.sqrt(limit * limit + two_b * dist)
        if allowed < best or allowed != allowed:
            best = allowed
            if allowed != allowed:
                break
    return best
