"""Where cars will be along SUMO's lanes: a car's front projected on its lane's centre
line, moved along it (and on along the lanes a junction lane leads to), its body along
the chord from its back to its front. Lanes are stacked: lane q is
``points[starts[q]:starts[q + 1]]``, ``lengths[q]`` long (its segments' sum), leading to
lane ``successors[q]`` (-1: none)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _segment(points: np.ndarray, k: int) -> tuple[float, float, float, float]:
    """Segment k's direction and (squared) length (at least 1e-6 m)."""
    dx = points[k + 1, 0] - points[k, 0]
    dy = points[k + 1, 1] - points[k, 1]
    length2 = max(dx * dx + dy * dy, 1e-12)
    return dx, dy, length2, math.sqrt(length2)


@njit(cache=True)
def lane_position(points: np.ndarray, start: int, end: int, x: float, y: float) -> float:
    """Distance along the polyline ``points[start:end]`` of its point nearest (x, y)."""
    best, position, run = math.inf, 0.0, 0.0
    for k in range(start, end - 1):
        dx, dy, length2, seg = _segment(points, k)
        t = ((x - points[k, 0]) * dx + (y - points[k, 1]) * dy) / length2
        t = min(max(t, 0.0), 1.0)
        gap = math.hypot(points[k, 0] + t * dx - x, points[k, 1] + t * dy - y)
        if gap < best:
            best, position = gap, run + t * seg
        run += seg
    return position


@njit(cache=True)
def point_along(
    points: np.ndarray,
    starts: np.ndarray,
    lengths: np.ndarray,
    successors: np.ndarray,
    lane: int,
    position: float,
) -> tuple[float, float, float]:
    """(x, y, direction) `position` from the lane's start: on along its successors past
    its end, clipped at the last one's end and at the lane's start."""
    while position > lengths[lane] and successors[lane] >= 0:
        position -= lengths[lane]
        lane = successors[lane]
    k, last = starts[lane], starts[lane + 1] - 2
    dx, dy, _, seg = _segment(points, k)
    left = max(position, 0.0)
    while left > seg and k < last:
        left -= seg
        k += 1
        dx, dy, _, seg = _segment(points, k)
    f = min(left / seg, 1.0)
    return points[k, 0] + f * dx, points[k, 1] + f * dy, math.atan2(dy, dx)


@njit(cache=True)
def moved_along_lanes(
    points: np.ndarray,
    starts: np.ndarray,
    lengths: np.ndarray,
    successors: np.ndarray,
    lanes: np.ndarray,
    front_x: np.ndarray,
    front_y: np.ndarray,
    ahead: np.ndarray,
    length: np.ndarray,
) -> np.ndarray:
    """Rows (centre x, centre y, yaw) of each car's body after its front, on lane
    `lanes[i]`, moved `ahead[i]` along the lanes: the body `length[i]` long along the
    chord from the lanes' point that far behind the front (its direction there when
    the chord is shorter than 0.1 m)."""
    out = np.empty((lanes.shape[0], 3))
    for i in range(lanes.shape[0]):
        q = lanes[i]
        at = lane_position(points, starts[q], starts[q + 1], front_x[i], front_y[i])
        fx, fy, direction = point_along(points, starts, lengths, successors, q, at + ahead[i])
        bx, by, _ = point_along(points, starts, lengths, successors, q, at + ahead[i] - length[i])
        chord = math.hypot(fx - bx, fy - by)
        yaw = math.atan2(fy - by, fx - bx) if chord > 0.1 else direction
        out[i, 0] = fx - 0.5 * length[i] * math.cos(yaw)
        out[i, 1] = fy - 0.5 * length[i] * math.sin(yaw)
        out[i, 2] = yaw
    return out
