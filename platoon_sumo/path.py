"""A route's centre-line as an arc-length parametrised polyline.

Controllers track it, the loop measures progress and lateral offset on it. Points are
resampled at a fixed spacing so that look-ups are index arithmetic, not searches. The
per-step look-ups (``project``, ``point_at``, ``heading_at``, ``lane_step``) are scalar
arithmetic on cached Python lists and compiled kernels (``platoon_sumo.kernels.route``:
the projection searches only the blocks of the window that can hold the nearest point,
the lane request reads lanes as numbers): a microsecond or two a call. The arrays the
kernels need are cached on the path (``kernel_arrays``), so controllers that do their
whole step in one kernel (``RouteFollowing``) share them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.kernels.route import (
    lane_step_kernel,
    path_blocks,
    project_members,
    project_pruned,
    same_lane_kernel,
)

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


@dataclass(frozen=True)
class StraightCrossing:
    """A straight-through connection of the route (netconvert's direction "s"): its
    junction lanes and their chord, from the first lane's start to the last one's end,
    as it advances along the direction of the lane before and moves sideways."""

    lane_ids: tuple[str, ...]
    advance_m: float
    sideways_m: float
    width_m: float
    """The first junction lane's width."""

    def is_jog(self, min_radius_m: float, body_width_m: float) -> bool:
        """Does it move the lane sideways, out of the lane's room beside a body this
        wide, within less advance than a vehicle turning no tighter than `min_radius_m`
        needs for that shift (two opposite arcs: radius (a² + d²) / 4d)? SUMO moves its
        cars across such a jog, front on the lane and back on the lane before; none
        drives it as a bend."""
        d, a = self.sideways_m, self.advance_m
        if d <= 0.5 * max(self.width_m - body_width_m, 0.0):
            return False
        return a <= 0.0 or (a * a + d * d) / (4.0 * d) < min_radius_m


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
    straight_crossings: tuple[StraightCrossing, ...] = ()

    def jog_lanes(self, min_radius_m: float, body_width_m: float) -> frozenset[str]:
        """The junction lanes of the route's straight-through connections that are jogs
        for a vehicle of this turning radius and width (``StraightCrossing.is_jog``)."""
        return frozenset(
            lane
            for c in self.straight_crossings
            if c.is_jog(min_radius_m, body_width_m)
            for lane in c.lane_ids
        )

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
        straight_crossings: Sequence[StraightCrossing] = (),
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
            straight_crossings=tuple(straight_crossings),
        )

    # Derived values are cached on first use (the path never changes; cached_property
    # writes the instance __dict__, which a frozen dataclass allows).

    @cached_property
    def length_m(self) -> float:
        return float((len(self.xy_m) - 2) * self.spacing_m + self._last_step)

    @cached_property
    def _last_step(self) -> float:
        return float(np.hypot(*(self.xy_m[-1] - self.xy_m[-2])))

    @cached_property
    def left_normals(self) -> FloatArray:
        """(n, 2) unit normals to the left of the path at each point (from the chord
        through its neighbours)."""
        xy = self.xy_m
        tangent = np.empty_like(xy)
        if len(xy) < 2:
            tangent[:] = (1.0, 0.0)
        else:
            tangent[1:-1] = xy[2:] - xy[:-2]
            tangent[0], tangent[-1] = xy[1] - xy[0], xy[-1] - xy[-2]
        norm = np.maximum(np.hypot(tangent[:, 0], tangent[:, 1]), 1e-12)
        return np.column_stack([-tangent[:, 1] / norm, tangent[:, 0] / norm])

    @cached_property
    def _xy(self) -> list[list[float]]:
        """``xy_m`` as nested lists: scalar look-ups without numpy indexing."""
        return self.xy_m.tolist()

    @cached_property
    def _xy_c(self) -> FloatArray:
        """``xy_m`` as a C-contiguous float64 array for the projection kernel."""
        return np.ascontiguousarray(self.xy_m, dtype=np.float64)

    @cached_property
    def _lane_width_c(self) -> FloatArray:
        return np.ascontiguousarray(self.lane_width_m, dtype=np.float64)

    @cached_property
    def _blocks(self) -> FloatArray:
        """Bounding circles of the segments, ``BLOCK`` at a time (``path_blocks``)."""
        return path_blocks(self._xy_c)

    @cached_property
    def _lane_codes(self) -> NDArray[np.int64]:
        """Per point (edge number, lane index) of ``_lane_key_of_point`` for
        ``lane_step_kernel`` (edge -1: a junction lane); no rows when a lane id does not
        read as ``EDGE_INDEX`` (``lane_step`` then runs in Python)."""
        edges: dict[str, int] = {}
        per_lane = []
        for id_ in self.lane_ids:
            if id_.startswith(":"):
                per_lane.append((-1, 0))
                continue
            key = id_.rsplit("_", 1)
            if len(key) != 2:
                return np.zeros((0, 2), dtype=np.int64)
            try:
                index = int(key[1])
            except ValueError:
                return np.zeros((0, 2), dtype=np.int64)
            if abs(index) >= 2**62:
                return np.zeros((0, 2), dtype=np.int64)
            per_lane.append((edges.setdefault(key[0], len(edges)), index))
        table = np.array(per_lane, dtype=np.int64).reshape(-1, 2)
        return np.ascontiguousarray(table[np.asarray(self.lane_index, dtype=np.int64)])

    @cached_property
    def _lane_spans_c(self) -> FloatArray:
        return np.array(self._lane_change_spans, dtype=np.float64).reshape(-1, 2)

    @cached_property
    def kernel_arrays(
        self,
    ) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.int64], FloatArray, FloatArray]:
        """What ``platoon_sumo.kernels.route.route_step_kernel`` reads of the path: the
        points, their blocks, lane widths, lane codes, lane-change spans and
        (spacing, length, last step)."""
        geometry = np.array([self.spacing_m, self.length_m, self._last_step], dtype=np.float64)
        return (
            self._xy_c, self._blocks, self._lane_width_c, self._lane_codes,
            self._lane_spans_c, geometry,
        )  # fmt: skip

    @cached_property
    def follower_kernel_arrays(
        self,
    ) -> tuple[
        FloatArray, FloatArray, FloatArray, NDArray[np.int64], FloatArray, FloatArray, FloatArray
    ]:
        """What ``platoon_sumo.kernels.following.following_step_kernel`` reads of the
        path: ``kernel_arrays`` with the lane shift per point (``_lane_shift``) before
        the geometry."""
        xy, blocks, widths, codes, spans, geometry = self.kernel_arrays
        return xy, blocks, widths, codes, spans, self._lane_shift_c, geometry

    @cached_property
    def _lane_width(self) -> list[float]:
        return [float(w) for w in self.lane_width_m]

    @cached_property
    def _lane_of_point(self) -> list[str]:
        return [self.lane_ids[int(i)] for i in self.lane_index]

    @cached_property
    def _junction_points_before(self) -> list[int]:
        """Per point index i (and one past the end): how many points before i lie on a
        junction's internal lane (a prefix count: a stretch is one subtraction)."""
        internal = np.array([id_.startswith(":") for id_ in self.lane_ids], dtype=bool)
        on_junction = internal[np.asarray(self.lane_index, dtype=np.intp)]
        return [0, *np.cumsum(on_junction, dtype=np.int64).tolist()]

    def junction_within(self, from_s_m: float, to_s_m: float) -> bool:
        """Does any of the path from `from_s_m` to `to_s_m` run inside a junction?"""
        before = self._junction_points_before
        n = len(before) - 1
        i0 = min(max(int(from_s_m // self.spacing_m), 0), n)
        i1 = min(max(int(to_s_m // self.spacing_m) + 2, 0), n)
        return i1 > i0 and before[i1] > before[i0]

    @cached_property
    def _lane_key_of_point(self) -> list[tuple[str, ...] | None]:
        """(edge, lane index as text) of the lane under each point; None in junctions."""
        keys = [None if id_.startswith(":") else tuple(id_.rsplit("_", 1)) for id_ in self.lane_ids]
        return [keys[int(i)] for i in self.lane_index]

    @cached_property
    def _lane_change_spans(self) -> list[tuple[float, float]]:
        return [(c.begin_s_m, c.end_s_m) for c in self.lane_changes]

    @property
    def s_m(self) -> FloatArray:
        s = np.arange(len(self.xy_m), dtype=np.float64) * self.spacing_m
        s[-1] = self.length_m
        return s

    def _index(self, s_m: float) -> int:
        # min/max like np.clip (a NaN stays NaN and int() refuses it)
        return int(min(max(s_m // self.spacing_m, 0), len(self.xy_m) - 2))

    def point_at(self, s_m: float) -> tuple[float, float]:
        """Position at arc length s (clamped to the path)."""
        s = float(min(max(s_m, 0.0), self.length_m))
        spacing, last = self.spacing_m, len(self.xy_m) - 2
        i = int(min(s // spacing, last))  # s >= 0 (NaN: int() refuses it, as before)
        step = spacing if i < last else self._last_step
        t = (s - i * spacing) / step if step > 0 else 0.0
        t = min(max(t, 0.0), 1.0)
        xy = self._xy
        (x0, y0), (x1, y1) = xy[i], xy[i + 1]
        return x0 + (x1 - x0) * t, y0 + (y1 - y0) * t

    def heading_at(self, s_m: float) -> float:
        """Direction of travel at s [rad, counter-clockwise from +x]."""
        i = self._index(float(min(max(s_m, 0.0), self.length_m)))
        xy = self._xy
        (x0, y0), (x1, y1) = xy[i], xy[i + 1]
        return math.atan2(y1 - y0, x1 - x0)

    def lane_width_near(self, s_m: float) -> float:
        """Width of the lane under the path point at or before arc length s (clamped)."""
        i = min(int(max(s_m, 0.0) // self.spacing_m), len(self.xy_m) - 1)
        return self._lane_width[i]

    def lane_at(self, s_m: float) -> str:
        i = min(int(max(s_m, 0.0) // self.spacing_m), len(self.xy_m) - 1)
        return self._lane_of_point[i]

    def lane_beside(self, s_m: float, lateral_offset_m: float) -> tuple[str, int] | None:
        """(edge, lane index) of the lane `lateral_offset_m` (left +) beside the path at
        `s_m`; None in junctions and lane-change stretches, where the path lies between
        lanes."""
        if self._in_lane_change(s_m, s_m):
            return None
        return self._lane_of(s_m, lateral_offset_m)

    def lane_step(
        self, s_m: float, offset_m: float, target_s_m: float, target_offset_m: float
    ) -> int:
        """+1 / -1 when the target point lies in the lane to the left / right (or further)
        of the point's lane on the same edge; 0 otherwise, and where either lies in a
        junction or a lane-change stretch (lanes compared by the map, not by offsets)."""
        codes = self._lane_codes
        if len(codes):
            step = lane_step_kernel(
                codes, self._lane_width_c, self._lane_spans_c, self.spacing_m, float(s_m),
                float(offset_m), float(target_s_m), float(target_offset_m),
            )  # fmt: skip
            if step != -2:
                return int(step)
        # (an unusual lane id, or a value that raises below) in Python
        if self._in_lane_change(s_m, target_s_m):
            return 0
        own = self._lane_of(s_m, offset_m)
        target = self._lane_of(target_s_m, target_offset_m)
        if own is None or target is None or own[0] != target[0] or own[1] == target[1]:
            return 0
        return 1 if target[1] > own[1] else -1

    def same_lane(
        self, s_m: float, offset_m: float, target_s_m: float, target_offset_m: float
    ) -> bool:
        """Do both points lie in the same lane of the same edge (outside junctions)? Also
        along the route's lane changes, where the path runs between lanes
        (`_lane_shift`)."""
        codes = self._lane_codes
        if len(codes):
            same = same_lane_kernel(
                codes, self._lane_width_c, self._lane_shift_c, self.spacing_m, float(s_m),
                float(offset_m), float(target_s_m), float(target_offset_m),
            )  # fmt: skip
            if same != -2:
                return same == 1
        # (an unusual lane id, or a value that raises below) in Python
        if not all(math.isfinite(v) for v in (s_m, offset_m, target_s_m, target_offset_m)):
            return False
        own = self._lane_of(s_m, offset_m, shifted=True)
        return own is not None and own == self._lane_of(target_s_m, target_offset_m, True)

    def _in_lane_change(self, s_m: float, target_s_m: float) -> bool:
        return any(
            begin <= s_m <= end or begin <= target_s_m <= end
            for begin, end in self._lane_change_spans
        )

    def _lane_of(
        self, s_m: float, offset_m: float, shifted: bool = False
    ) -> tuple[str, int] | None:
        """(edge, lane index) of the point `offset_m` beside the path at `s_m`, counted
        by lane widths from the lane the point's lane id names (`shifted`: from where the
        path centre runs, `_lane_shift`); None in a junction."""
        i = min(int(max(s_m, 0.0) // self.spacing_m), len(self.xy_m) - 1)
        key = self._lane_key_of_point[i]
        if key is None:
            return None
        lanes = offset_m / self._lane_width[i] + (self._lane_shift[i] if shifted else 0.0)
        return key[0], int(key[1]) + round(lanes)

    @cached_property
    def _lane_shift_c(self) -> FloatArray:
        return np.array(self._lane_shift, dtype=np.float64)

    @cached_property
    def _lane_shift(self) -> list[float]:
        """Per point: lanes (left +) between the path centre and the lane its lane id
        names. A route's lane change blends one lane's shape into the other's inside one
        edge and keeps the first lane's id (`network.route_path`): across the change the
        shift grows as the blend's smoothstep to the lanes changed, and stays there to
        the edge's end."""
        n = len(self.xy_m)
        shift = np.zeros(n)
        s = np.arange(n) * self.spacing_m
        keys, owner = self._lane_key_of_point, np.asarray(self.lane_index)
        for change in self.lane_changes:
            i0 = min(max(int(change.begin_s_m // self.spacing_m), 0), n - 1)
            key = keys[i0]
            target = change.target_lane_ids[-1].rsplit("_", 1) if change.target_lane_ids else []
            if key is None or len(target) != 2 or not target[1].lstrip("-").isdigit():
                continue
            lanes = int(target[1]) - int(key[1])
            piece = owner == owner[i0]
            span = max(change.end_s_m - change.begin_s_m, 1e-9)
            u = np.clip((s - change.begin_s_m) / span, 0.0, 1.0)
            edge = piece & (s >= change.begin_s_m)
            shift[edge] = lanes * (u * u * (3.0 - 2.0 * u))[edge]
        return [float(v) for v in shift]

    def project(
        self, x_m: float, y_m: float, s_hint_m: float | None = None, window_m: float = 20.0
    ) -> PathPoint:
        """Nearest point of the path to (x, y).

        With a hint, only the part of the path within `window_m` of it is searched, so a
        route that passes the same place twice (a loop, a grid) does not jump ahead.
        """
        s, lateral = self.project_sl(x_m, y_m, s_hint_m, window_m)
        return PathPoint(s_m=s, lateral_offset_m=lateral)

    def project_sl(
        self, x_m: float, y_m: float, s_hint_m: float | None = None, window_m: float = 20.0
    ) -> tuple[float, float]:
        """``project`` as a plain (arc length, lateral offset) pair, for per-step callers."""
        s, lateral, _ = self.project_lane(x_m, y_m, s_hint_m, window_m)
        return s, lateral

    def project_lane(
        self, x_m: float, y_m: float, s_hint_m: float | None = None, window_m: float = 20.0
    ) -> tuple[float, float, float]:
        """``project_sl`` and the width of the lane there (``lane_width_near`` of the arc
        length): (arc length, lateral offset, lane width)."""
        if s_hint_m is None:
            hint, window, use_hint = 0.0, 0.0, False
        else:
            hint, window, use_hint = _checked_hint(s_hint_m, window_m), float(window_m), True
        return project_pruned(
            self._xy_c, self._blocks, self._lane_width_c, self.spacing_m, self.length_m,
            use_hint, hint, window, float(x_m), float(y_m),
        )  # fmt: skip

    def project_sl_many(
        self, x_m: FloatArray, y_m: FloatArray, s_hint_m: float, window_m: float = 20.0
    ) -> tuple[FloatArray, FloatArray]:
        """``project_sl`` of many points with one hint, in one kernel call: (arc lengths,
        lateral offsets)."""
        hint = _checked_hint(s_hint_m, window_m)
        n = len(x_m)
        return project_members(
            self._xy_c, np.array([0, len(self._xy_c)]), self._blocks,
            np.array([0, len(self._blocks)]), self._lane_width_c,
            np.array([[self.spacing_m, self.length_m]]), np.zeros(n, dtype=np.int64),
            np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64),
            np.full(n, hint), np.full(n, float(window_m)),
        )  # fmt: skip

    def curvature_1pm(
        self, smoothing_m: float, left_out: frozenset[str] = frozenset()
    ) -> FloatArray:
        """Unsigned curvature at every point, averaged over `smoothing_m` of arc length.
        Points on the lanes `left_out` and their corners with the lanes before and
        after count 0 (see ``StraightCrossing.is_jog``)."""
        d = np.diff(self.xy_m, axis=0)
        heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
        seg = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        kappa = np.zeros(len(self.xy_m))
        if len(heading) > 1:
            kappa[1:-1] = np.abs(np.diff(heading)) / (0.5 * (seg[1:] + seg[:-1]))
        if left_out:
            out = np.array([id_ in left_out for id_ in self.lane_ids], dtype=bool)
            at = out[np.asarray(self.lane_index, dtype=np.intp)]
            near = at.copy()  # a point's curvature uses its neighbours: theirs count too
            near[1:] |= at[:-1]
            near[:-1] |= at[1:]
            kappa[near] = 0.0
        width = max(1, round(smoothing_m / self.spacing_m))
        kernel = np.ones(width) / width
        return np.asarray(np.convolve(kappa, kernel, mode="same"), dtype=np.float64)


def _checked_hint(s_hint_m: float, window_m: float) -> float:
    """A projection's hint as a float; a ValueError unless it and the window are finite
    and the window is not negative."""
    hint = float(s_hint_m)
    if not (math.isfinite(hint) and 0.0 <= float(window_m) < math.inf):
        raise ValueError(
            f"project: s_hint_m must be finite and window_m >= 0 and finite, got "
            f"{s_hint_m!r} and {window_m!r}"
        )
    return hint
