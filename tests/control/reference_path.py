"""REFERENCE ONLY (test oracle): the ``RoutePath`` look-ups as they were before the fast
path (``platoon_sumo/path.py``: numpy over the search window), as free functions of a
path, kept so the equivalence tests and ``tools/bench_controllers.py`` can compare the
new methods with them. Do not use in package code, do not change.
"""

from __future__ import annotations

import numpy as np

from platoon_sumo.path import PathPoint, RoutePath


def length_m(path: RoutePath) -> float:
    return float((len(path.xy_m) - 2) * path.spacing_m + _last_step(path))


def _last_step(path: RoutePath) -> float:
    return float(np.hypot(*(path.xy_m[-1] - path.xy_m[-2])))


def _index(path: RoutePath, s_m: float) -> int:
    return int(np.clip(s_m // path.spacing_m, 0, len(path.xy_m) - 2))


def point_at(path: RoutePath, s_m: float) -> tuple[float, float]:
    """Position at arc length s (clamped to the path)."""
    s = float(np.clip(s_m, 0.0, length_m(path)))
    i = _index(path, s)
    step = path.spacing_m if i < len(path.xy_m) - 2 else _last_step(path)
    t = (s - i * path.spacing_m) / step if step > 0 else 0.0
    p = path.xy_m[i] + (path.xy_m[i + 1] - path.xy_m[i]) * min(max(t, 0.0), 1.0)
    return float(p[0]), float(p[1])


def heading_at(path: RoutePath, s_m: float) -> float:
    """Direction of travel at s [rad, counter-clockwise from +x]."""
    i = _index(path, float(np.clip(s_m, 0.0, length_m(path))))
    d = path.xy_m[i + 1] - path.xy_m[i]
    return float(np.arctan2(d[1], d[0]))


def lane_at(path: RoutePath, s_m: float) -> str:
    i = min(int(max(s_m, 0.0) // path.spacing_m), len(path.xy_m) - 1)
    return path.lane_ids[int(path.lane_index[i])]


def _lanes_beside(path: RoutePath, s_m: float, lanes: float) -> tuple[str, int] | None:
    """(edge, lane index) `lanes` lane widths beside the lane at `s_m`; None in a junction."""
    lane = lane_at(path, s_m)
    if lane.startswith(":"):
        return None
    edge, index = lane.rsplit("_", 1)
    return edge, int(index) + round(lanes)


def _width_at(path: RoutePath, s_m: float) -> float:
    return float(path.lane_width_m[min(int(max(s_m, 0.0) // path.spacing_m), len(path.xy_m) - 1)])


def lane_beside(path: RoutePath, s_m: float, lateral_offset_m: float) -> tuple[str, int] | None:
    if any(c.begin_s_m <= s_m <= c.end_s_m for c in path.lane_changes):
        return None
    return _lanes_beside(path, s_m, lateral_offset_m / _width_at(path, s_m))


def lane_step(
    path: RoutePath, s_m: float, offset_m: float, target_s_m: float, target_offset_m: float
) -> int:
    own = lane_beside(path, s_m, offset_m)
    target = lane_beside(path, target_s_m, target_offset_m)
    if own is None or target is None or own[0] != target[0] or own[1] == target[1]:
        return 0
    return 1 if target[1] > own[1] else -1


def same_lane(
    path: RoutePath, s_m: float, offset_m: float, target_s_m: float, target_offset_m: float
) -> bool:
    """Both points in one lane of one edge, lanes counted from where the path centre runs
    (along a route's lane change it runs between lanes: `RoutePath._lane_shift`)."""

    def lane(s: float, offset: float) -> tuple[str, int] | None:
        if not (np.isfinite(s) and np.isfinite(offset)):
            return None
        i = min(int(max(s, 0.0) // path.spacing_m), len(path.xy_m) - 1)
        return _lanes_beside(path, s, offset / _width_at(path, s) + path._lane_shift[i])

    own = lane(s_m, offset_m)
    return own is not None and own == lane(target_s_m, target_offset_m)


def project(
    path: RoutePath, x_m: float, y_m: float, s_hint_m: float | None = None, window_m: float = 20.0
) -> PathPoint:
    """Nearest point of the path to (x, y), searched within `window_m` of the hint."""
    n_seg = len(path.xy_m) - 1
    if s_hint_m is None:
        lo, hi = 0, n_seg
    else:
        w = int(window_m / path.spacing_m) + 1
        centre = _index(path, s_hint_m)
        lo, hi = max(0, centre - w), min(n_seg, centre + w + 1)
    a = path.xy_m[lo:hi]
    d = path.xy_m[lo + 1 : hi + 1] - a
    rel = np.array([x_m, y_m]) - a
    seg_len2 = np.einsum("ij,ij->i", d, d)
    t = np.clip(np.einsum("ij,ij->i", rel, d) / np.maximum(seg_len2, 1e-18), 0.0, 1.0)
    closest = a + d * t[:, None]
    dist2 = np.einsum("ij,ij->i", closest - [x_m, y_m], closest - [x_m, y_m])
    k = int(np.argmin(dist2))
    cross = d[k, 0] * rel[k, 1] - d[k, 1] * rel[k, 0]
    seg_len = float(np.sqrt(seg_len2[k]))
    s = (lo + k) * path.spacing_m + float(t[k]) * seg_len
    return PathPoint(
        s_m=min(s, length_m(path)),
        lateral_offset_m=float(np.copysign(np.sqrt(dist2[k]), cross)),
    )
