"""A route's centre-line as an arc-length parametrised polyline (pure numpy).

Controllers track it, the loop measures progress and lateral offset on it. Points are
resampled at a fixed spacing so that look-ups are index arithmetic, not searches.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PathPoint:
    """Where a position lies on a path: arc length and signed lateral offset (left +)."""

    s_m: float
    lateral_offset_m: float


@dataclass(frozen=True)
class LaneChange:
    """A stretch of the path that moves sideways into other lanes of the same edge."""

    begin_s_m: float
    end_s_m: float
    target_lane_ids: tuple[str, ...]
    """The lanes entered, in order (one for a single change)."""
    begin_lane_pos_m: float = 0.0
    """Where it begins, measured along the target lanes from their start."""


@dataclass(frozen=True, eq=False)
class RoutePath:
    """Centre-line of a route, resampled every `spacing_m`.

    `lane_index[i]` indexes `lane_ids` (the SUMO lane under point i, internal junction
    lanes included) and `speed_limit_mps[i]` is that lane's speed limit.
    """

    xy_m: FloatArray
    spacing_m: float
    speed_limit_mps: FloatArray
    lane_index: NDArray[np.int64]
    lane_ids: tuple[str, ...]
    lane_width_m: FloatArray
    lane_changes: tuple[LaneChange, ...] = ()

    def next_lane_change(self, s_m: float) -> LaneChange | None:
        """The lane change under way at arc length `s_m`, or the next one (None: no more)."""
        return next((c for c in self.lane_changes if c.end_s_m > s_m), None)

    @classmethod
    def from_pieces(
        cls,
        pieces: Sequence[FloatArray],
        lane_ids: Sequence[str],
        speed_limits_mps: Sequence[float],
        lane_widths_m: Sequence[float],
        spacing_m: float,
        lane_changes: Sequence[LaneChange] = (),
    ) -> RoutePath:
        """Join per-lane polylines (each (k, 2)) into one path resampled at `spacing_m`."""
        if spacing_m <= 0:
            raise ValueError("spacing_m must be > 0")
        points: list[FloatArray] = []
        owner: list[NDArray[np.int64]] = []
        for i, piece in enumerate(pieces):
            arr = np.asarray(piece, dtype=np.float64).reshape(-1, 2)
            if points and len(arr) and np.allclose(points[-1][-1], arr[0], atol=1e-9):
                arr = arr[1:]
            points.append(arr)
            owner.append(np.full(len(arr), i, dtype=np.int64))
        xy = np.concatenate(points)
        who = np.concatenate(owner)
        seg = np.hypot(*np.diff(xy, axis=0).T)
        keep = np.concatenate([[True], seg > 1e-9])  # drop repeated points
        xy, who = xy[keep], who[keep]
        s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        if len(xy) < 2 or s[-1] <= 0:
            raise ValueError("a route path needs at least two distinct points")
        s_new = np.arange(0.0, s[-1], spacing_m)
        if s[-1] - s_new[-1] > 1e-9:
            s_new = np.append(s_new, s[-1])
        resampled = np.column_stack([np.interp(s_new, s, xy[:, 0]), np.interp(s_new, s, xy[:, 1])])
        # A segment belongs to the piece of its end vertex (pieces joined end to start
        # lose their duplicate first vertex), so a point takes the next vertex's piece.
        idx = np.clip(np.searchsorted(s, s_new, side="left"), 0, len(s) - 1)
        lane_of_point = who[idx]
        return cls(
            xy_m=resampled,
            spacing_m=spacing_m,
            speed_limit_mps=np.asarray(speed_limits_mps, dtype=np.float64)[lane_of_point],
            lane_index=lane_of_point,
            lane_ids=tuple(lane_ids),
            lane_width_m=np.asarray(lane_widths_m, dtype=np.float64)[lane_of_point],
            lane_changes=tuple(lane_changes),
        )

    @property
    def length_m(self) -> float:
        return float((len(self.xy_m) - 2) * self.spacing_m + self._last_step)

    @property
    def _last_step(self) -> float:
        return float(np.hypot(*(self.xy_m[-1] - self.xy_m[-2])))

    @property
    def s_m(self) -> FloatArray:
        s = np.arange(len(self.xy_m), dtype=np.float64) * self.spacing_m
        s[-1] = self.length_m
        return s

    def _index(self, s_m: float) -> int:
        return int(np.clip(s_m // self.spacing_m, 0, len(self.xy_m) - 2))

    def point_at(self, s_m: float) -> tuple[float, float]:
        """Position at arc length s (clamped to the path)."""
        s = float(np.clip(s_m, 0.0, self.length_m))
        i = self._index(s)
        step = self.spacing_m if i < len(self.xy_m) - 2 else self._last_step
        t = (s - i * self.spacing_m) / step if step > 0 else 0.0
        p = self.xy_m[i] + (self.xy_m[i + 1] - self.xy_m[i]) * min(max(t, 0.0), 1.0)
        return float(p[0]), float(p[1])

    def heading_at(self, s_m: float) -> float:
        """Direction of travel at s [rad, counter-clockwise from +x]."""
        i = self._index(float(np.clip(s_m, 0.0, self.length_m)))
        d = self.xy_m[i + 1] - self.xy_m[i]
        return float(np.arctan2(d[1], d[0]))

    def lane_at(self, s_m: float) -> str:
        i = min(int(max(s_m, 0.0) // self.spacing_m), len(self.xy_m) - 1)
        return self.lane_ids[int(self.lane_index[i])]

    def lane_beside(self, s_m: float, lateral_offset_m: float) -> tuple[str, int] | None:
        """(edge, lane index) of the lane `lateral_offset_m` (left +) beside the path at
        `s_m`; None in junctions and lane-change stretches, where the path lies between
        lanes."""
        if any(c.begin_s_m <= s_m <= c.end_s_m for c in self.lane_changes):
            return None
        lane = self.lane_at(s_m)
        if lane.startswith(":"):
            return None
        edge, index = lane.rsplit("_", 1)
        i = min(int(max(s_m, 0.0) // self.spacing_m), len(self.lane_width_m) - 1)
        return edge, int(index) + round(lateral_offset_m / float(self.lane_width_m[i]))

    def lane_step(
        self, s_m: float, offset_m: float, target_s_m: float, target_offset_m: float
    ) -> int:
        """+1 / -1 when the target point lies in the lane to the left / right (or further)
        of the point's lane on the same edge; 0 otherwise, and where either lies in a
        junction or a lane-change stretch (lanes compared by the map, not by offsets)."""
        own = self.lane_beside(s_m, offset_m)
        target = self.lane_beside(target_s_m, target_offset_m)
        if own is None or target is None or own[0] != target[0] or own[1] == target[1]:
            return 0
        return 1 if target[1] > own[1] else -1

    def project(
        self, x_m: float, y_m: float, s_hint_m: float | None = None, window_m: float = 20.0
    ) -> PathPoint:
        """Nearest point of the path to (x, y).

        With a hint, only the part of the path within `window_m` of it is searched, so a
        route that passes the same place twice (a loop, a grid) does not jump ahead.
        """
        n_seg = len(self.xy_m) - 1
        if s_hint_m is None:
            lo, hi = 0, n_seg
        else:
            w = int(window_m / self.spacing_m) + 1
            centre = self._index(s_hint_m)
            lo, hi = max(0, centre - w), min(n_seg, centre + w + 1)
        a = self.xy_m[lo:hi]
        d = self.xy_m[lo + 1 : hi + 1] - a
        rel = np.array([x_m, y_m]) - a
        seg_len2 = np.einsum("ij,ij->i", d, d)
        t = np.clip(np.einsum("ij,ij->i", rel, d) / np.maximum(seg_len2, 1e-18), 0.0, 1.0)
        closest = a + d * t[:, None]
        dist2 = np.einsum("ij,ij->i", closest - [x_m, y_m], closest - [x_m, y_m])
        k = int(np.argmin(dist2))
        cross = d[k, 0] * rel[k, 1] - d[k, 1] * rel[k, 0]
        seg_len = float(np.sqrt(seg_len2[k]))
        s = (lo + k) * self.spacing_m + float(t[k]) * seg_len
        return PathPoint(
            s_m=min(s, self.length_m),
            lateral_offset_m=float(np.copysign(np.sqrt(dist2[k]), cross)),
        )

    def curvature_1pm(self, smoothing_m: float) -> FloatArray:
        """Unsigned curvature at every point, averaged over `smoothing_m` of arc length."""
        d = np.diff(self.xy_m, axis=0)
        heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
        seg = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        kappa = np.zeros(len(self.xy_m))
        if len(heading) > 1:
            kappa[1:-1] = np.abs(np.diff(heading)) / (0.5 * (seg[1:] + seg[:-1]))
        width = max(1, round(smoothing_m / self.spacing_m))
        kernel = np.ones(width) / width
        return np.asarray(np.convolve(kappa, kernel, mode="same"), dtype=np.float64)
