"""Exact planar ray casting for the laser scanner, batched over many sensors (numpy only).

Why it is fast without giving up exactness:

* Everything is one ray-segment kernel. A rectangle contributes only the edges that face
  the sensor (at most 2; all 4 when the sensor is inside it): the first hit on a convex
  shape from outside is always on a facing edge, so the other edges can never win.
* A segment seen from the sensor covers a wedge of directions. Rays are evenly spaced,
  so the wedge maps to a contiguous run of ray indices, and only those (ray, segment)
  pairs are evaluated: every evaluated pair is a hit, none is wasted on a miss. The
  work is the sum of the obstacles' angular sizes, not rays x segments.
* Adjacent edges of a rectangle share their corner floats, so the ray-index bound of a
  corner is computed identically for both edges: no ray leaks through a corner.
* A uniform grid, built once per call, gives each sensor the obstacles within
  ``range_max`` of it, so the cost depends on what is near each sensor only.
* All sensors' (ray, segment) pairs are evaluated together in a few large numpy
  operations (chunked to bound memory), so there is no Python loop per sensor.

Hit identities (``return_hits=True``): every evaluated pair carries the index of its
obstacle, and after a chunk's ``minimum.at`` the pairs whose distance equals the ray's
new minimum are its winners; a second ``minimum.at`` keeps the lowest winning index
per ray, so a tie (a shared corner, a duplicated obstacle) resolves to the lower index
whatever the batching or chunking. A ray whose minimum drops in a later chunk forgets
the identity it had (only rays of sensors met in an earlier chunk need that check).
The distances take the same path as without identities, so the ranges are
bit-identical.

Hit distance along a ray of unit direction d from the sensor to the line through a with
direction e: ``t = cross(a, e) / cross(d, e)``.
"""

from __future__ import annotations

import math
from statistics import NormalDist
from typing import Literal, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from platoon_sumo.geometry import as_rectangles, rectangle_corners
from platoon_sumo.kernels.raycast import evaluate_runs
from platoon_sumo.sensors.laser import LaserConfig

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

_TWO_PI = 2.0 * math.pi
#: Obstacles farther than range_max + this are culled; the slack keeps culling from
#: ever disagreeing with the kernel's own rounding at the range limit.
_CULL_SLACK_M = 1e-6
#: Hit identity of a ray without a return (``+inf`` or a ``NaN`` dropout).
NO_RETURN = -1
#: Working identity of a ray no evaluated pair has won yet (above every real index).
_UNSET = np.iinfo(np.intp).max


@overload
def cast_rays(
    origin: ArrayLike,
    heading: float,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: Literal[False] = ...,
) -> FloatArray: ...


@overload
def cast_rays(
    origin: ArrayLike,
    heading: float,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: Literal[True],
) -> tuple[FloatArray, IntArray]: ...


@overload
def cast_rays(
    origin: ArrayLike,
    heading: float,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: bool,
) -> FloatArray | tuple[FloatArray, IntArray]: ...


def cast_rays(
    origin: ArrayLike,
    heading: float,
    config: LaserConfig,
    rectangles: ArrayLike | None = None,
    segments: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    *,
    return_hits: bool = False,
) -> FloatArray | tuple[FloatArray, IntArray]:
    """Ranges [m] of one scan, shape ``(samples,)``, REP 117 conventions.

    ``origin`` is the sensor position (x, y) [m], ``heading`` its forward direction
    [rad, CCW from +x]. ``rectangles`` is ``(N, 5)``: centre_x, centre_y, yaw, length
    (along yaw), width; ``segments`` is ``(M, 4)``: x1, y1, x2, y2. Without noise each
    finite reading is the exact distance to the first surface on the ray (to rounding).

    A sensor strictly inside a rectangle sees that rectangle's inner walls (usually
    closer than range_min, so ``-inf``); a sensor exactly on a surface reads 0 on every
    ray. Noise and dropouts need ``rng`` (see ``apply_noise``).

    With ``return_hits=True`` the result is ``(ranges, hits)``: ``hits`` (intp, same
    shape) names the obstacle each reading comes from: ``i`` for ``rectangles[i]``,
    ``N + j`` for ``segments[j]``, ``NO_RETURN`` (-1) where the reading is ``+inf`` or a
    ``NaN`` dropout; a ``-inf`` reading keeps the identity of the too-close surface.
    Surfaces at exactly the same distance on a ray give the lowest index (a sensor on a
    surface: the lowest surface it touches, on every ray). The ranges and the draws from
    ``rng`` are the same as with ``return_hits=False``.
    """
    origins = np.asarray(origin, dtype=np.float64).reshape(1, 2)
    headings = np.asarray([heading], dtype=np.float64)
    rects, segs = obstacle_arrays(rectangles, segments)
    raw, hits = _raw_ranges(
        origins, headings, config, rects, segs, None, use_grid=False, with_hits=return_hits
    )
    ranges = _finish(raw, config, rng)
    if hits is None:
        return ranges[0]
    return ranges[0], _no_return(hits, ranges)[0]


@overload
def scan_many(
    origins: ArrayLike,
    headings: ArrayLike,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    exclude: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: Literal[False] = ...,
) -> FloatArray: ...


@overload
def scan_many(
    origins: ArrayLike,
    headings: ArrayLike,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    exclude: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: Literal[True],
) -> tuple[FloatArray, IntArray]: ...


@overload
def scan_many(
    origins: ArrayLike,
    headings: ArrayLike,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    exclude: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: bool,
) -> FloatArray | tuple[FloatArray, IntArray]: ...


def scan_many(
    origins: ArrayLike,
    headings: ArrayLike,
    config: LaserConfig,
    rectangles: ArrayLike | None = None,
    segments: ArrayLike | None = None,
    exclude: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    *,
    return_hits: bool = False,
) -> FloatArray | tuple[FloatArray, IntArray]:
    """Ranges of K sensors at once, shape ``(K, samples)``.

    ``exclude[k]`` is the index of the rectangle that is sensor k's own vehicle (-1 for
    none). Row k equals ``cast_rays`` for sensor k with that rectangle removed; with
    noise, one generator gives the same draws batched or one sensor at a time.

    ``return_hits=True`` returns ``(ranges, hits)``, ``hits`` as in ``cast_rays`` with
    the indices into the full ``rectangles`` and ``segments`` passed here (row k never
    names ``exclude[k]``).
    """
    pos = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    head = np.asarray(headings, dtype=np.float64).reshape(-1)
    if head.shape[0] != pos.shape[0]:
        raise ValueError(f"headings: expected {pos.shape[0]} values, got {head.shape[0]}")
    excl = None
    if exclude is not None:
        excl = np.asarray(exclude, dtype=np.intp).reshape(-1)
        if excl.shape[0] != pos.shape[0]:
            raise ValueError(f"exclude: expected {pos.shape[0]} values, got {excl.shape[0]}")
    rects, segs = obstacle_arrays(rectangles, segments)
    raw, hits = _raw_ranges(
        pos, head, config, rects, segs, excl, use_grid=True, with_hits=return_hits
    )
    ranges = _finish(raw, config, rng)
    if hits is None:
        return ranges
    return ranges, _no_return(hits, ranges)


def apply_noise(
    ranges: FloatArray, config: LaserConfig, rng: np.random.Generator | None
) -> FloatArray:
    """Add Gaussian range noise to valid readings and NaN dropouts, in place.

    Each scan draws one ``(2, samples)`` block of standard normals: row 0 is the range
    noise, row 1 decides dropouts (``z < Phi^-1(p)`` has probability p). Drawing one
    block per scan is what makes batched and per-sensor scans reproduce each other.
    Noisy readings are clipped to [range_min, range_max] so finite stays in range.
    """
    if config.noise_std_m == 0.0 and config.dropout_prob == 0.0:
        return ranges
    if rng is None:
        raise ValueError(
            "rng: a numpy.random.Generator is required when noise_std_m > 0 or "
            "dropout_prob > 0 (e.g. numpy.random.default_rng(seed))"
        )
    k, n = ranges.shape
    z = rng.standard_normal((k, 2, n))
    if config.noise_std_m > 0.0:
        valid = np.isfinite(ranges)
        noisy = ranges[valid] + config.noise_std_m * z[:, 0, :][valid]
        ranges[valid] = np.clip(noisy, config.range_min_m, config.range_max_m)
    if config.dropout_prob > 0.0:
        threshold = NormalDist().inv_cdf(config.dropout_prob)
        ranges[z[:, 1, :] < threshold] = np.nan
    return ranges


# ----------------------------------------------------------------------------- internals


def obstacle_arrays(
    rectangles: ArrayLike | None, segments: ArrayLike | None
) -> tuple[FloatArray, FloatArray]:
    """Validated ``(N, 5)`` rectangles and ``(M, 4)`` segments; None or empty gives 0 rows."""
    rects = np.empty((0, 5))
    if rectangles is not None and np.size(rectangles):
        rects = as_rectangles(rectangles)
    segs = np.empty((0, 4))
    if segments is not None and np.size(segments):
        segs = np.asarray(segments, dtype=np.float64)
        if segs.ndim != 2 or segs.shape[1] != 4:
            raise ValueError(f"segments: expected shape (M, 4), got {segs.shape}")
    return rects, segs


def _finish(raw: FloatArray, config: LaserConfig, rng: np.random.Generator | None) -> FloatArray:
    """Raw first-hit distances -> REP 117 readings, then noise and dropouts."""
    if config.range_min_m == 0.0:
        np.maximum(raw, 0.0, out=raw)  # rounding can give -1e-17 for a touching surface
    raw[raw > config.range_max_m] = np.inf
    raw[raw < config.range_min_m] = -np.inf
    return apply_noise(raw, config, rng)


def _no_return(hits: IntArray, ranges: FloatArray) -> IntArray:
    """Final identities: ``NO_RETURN`` where the reading is ``+inf`` or ``NaN``."""
    np.putmask(hits, ~(ranges < np.inf), NO_RETURN)  # False for +inf and NaN only
    return hits


def _near_pairs(
    sensors: FloatArray, lo: FloatArray, hi: FloatArray, reach_m: float, use_grid: bool
) -> tuple[IntArray, IntArray]:
    """Candidate (sensor, object) pairs: every object whose bounding box [lo, hi] comes
    within ``reach_m`` of a sensor is included (a superset; exact culling follows).

    Grid: square cells of side ``reach_m / 2``; each object is listed in every cell its
    box touches and each sensor reads the 5 x 5 block of cells around its own.
    """
    k, n = sensors.shape[0], lo.shape[0]
    if n == 0 or k == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    if not use_grid:
        return np.repeat(np.arange(k), n), np.tile(np.arange(n), k)
    cell_m = 0.5 * reach_m
    origin = np.minimum(lo.min(axis=0), sensors.min(axis=0)) - 3.0 * cell_m
    top = np.maximum(hi.max(axis=0), sensors.max(axis=0))
    ny = int(np.floor((top[1] - origin[1]) / cell_m)) + 5
    cell_lo = np.floor((lo - origin) / cell_m).astype(np.intp)
    cell_hi = np.floor((hi - origin) / cell_m).astype(np.intp)
    span_x = cell_hi[:, 0] - cell_lo[:, 0] + 1
    span_y = cell_hi[:, 1] - cell_lo[:, 1] + 1
    per_obj = span_x * span_y
    multi_cell = bool(per_obj.max() > 1)
    if multi_cell:  # list each object in every cell of its box
        obj = np.repeat(np.arange(n), per_obj)
        local = np.arange(obj.size) - np.repeat(np.cumsum(per_obj) - per_obj, per_obj)
        keys = (cell_lo[obj, 0] + local // span_y[obj]) * ny + cell_lo[obj, 1] + local % span_y[obj]
    else:
        obj = np.arange(n)
        keys = cell_lo[:, 0] * ny + cell_lo[:, 1]
    order = np.argsort(keys, kind="stable")
    keys, obj = keys[order], obj[order]
    sc = np.floor((sensors - origin) / cell_m).astype(np.intp)
    block = (np.arange(-2, 3)[:, None] * ny + np.arange(-2, 3)[None, :]).ravel()
    query = (sc[:, 0] * ny + sc[:, 1])[:, None] + block[None, :]
    first = np.searchsorted(keys, query, side="left").ravel()
    count = np.searchsorted(keys, query, side="right").ravel() - first
    total = int(count.sum())
    sensor = np.repeat(np.repeat(np.arange(k), block.size), count)
    slot = np.arange(total) - np.repeat(np.cumsum(count) - count - first, count)
    pair_obj = obj[slot]
    if not multi_cell:
        return sensor, pair_obj
    # an object spanning several cells can be found more than once by one sensor
    key = np.unique(sensor * n + pair_obj)
    return key // n, key % n


def _facing_edges(
    sensors: FloatArray,
    rects: FloatArray,
    exclude: IntArray | None,
    reach_m: float,
    use_grid: bool,
) -> tuple[IntArray, IntArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Rectangle edges that can be a first hit: (sensor, rectangle, ax, ay, bx, by)."""
    corners = rectangle_corners(rects)  # front-right, front-left, rear-left, rear-right
    cxs, cys = corners[..., 0], corners[..., 1]
    # bucket by centre (one grid cell each, no duplicates), reach widened to compensate
    half_diag = 0.5 * np.hypot(rects[:, 3], rects[:, 4])
    centre = rects[:, 0:2]
    k, r = _near_pairs(sensors, centre, centre, reach_m + float(half_diag.max()), use_grid)
    if exclude is not None and k.size:
        keep = exclude[k] != r
        k, r = k[keep], r[keep]
    # sensor in each rectangle's own frame
    cos_yaw, sin_yaw = np.cos(rects[:, 2]), np.sin(rects[:, 2])
    c, s = cos_yaw[r], sin_yaw[r]
    dx, dy = sensors[k, 0] - rects[r, 0], sensors[k, 1] - rects[r, 1]
    lx, ly = c * dx + s * dy, c * dy - s * dx
    hl, hw = 0.5 * rects[r, 3], 0.5 * rects[r, 4]
    gap = np.hypot(np.maximum(np.abs(lx) - hl, 0.0), np.maximum(np.abs(ly) - hw, 0.0))
    near = gap <= reach_m
    k, r, lx, ly, hl, hw = k[near], r[near], lx[near], ly[near], hl[near], hw[near]
    facing = np.column_stack((lx >= hl, ly >= hw, lx <= -hl, ly <= -hw))
    facing[~facing.any(axis=1)] = True  # inside: every inner wall counts
    pair, edge = np.nonzero(facing)
    k, r = k[pair], r[pair]
    nxt = (edge + 1) % 4
    return k, r, cxs[r, edge], cys[r, edge], cxs[r, nxt], cys[r, nxt]


def _near_segments(
    sensors: FloatArray, segs: FloatArray, reach_m: float, use_grid: bool
) -> tuple[IntArray, IntArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Free segments within reach of each sensor: (sensor, segment, ax, ay, bx, by)."""
    lo = np.minimum(segs[:, 0:2], segs[:, 2:4])
    hi = np.maximum(segs[:, 0:2], segs[:, 2:4])
    k, m = _near_pairs(sensors, lo, hi, reach_m, use_grid)
    ax, ay, bx, by = segs[m, 0], segs[m, 1], segs[m, 2], segs[m, 3]
    px, py = sensors[k, 0], sensors[k, 1]
    ex, ey = bx - ax, by - ay
    length2 = ex * ex + ey * ey
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.clip(((px - ax) * ex + (py - ay) * ey) / length2, 0.0, 1.0)
    f = np.where(length2 > 0.0, f, 0.0)
    near = np.hypot(ax + f * ex - px, ay + f * ey - py) <= reach_m
    return k[near], m[near], ax[near], ay[near], bx[near], by[near]


def _raw_ranges(
    sensors: FloatArray,
    headings: FloatArray,
    config: LaserConfig,
    rects: FloatArray,
    segs: FloatArray,
    exclude: IntArray | None,
    use_grid: bool,
    with_hits: bool = False,
) -> tuple[FloatArray, IntArray | None]:
    """First-hit distance per ray (inf when nothing is hit), shape (K, samples), and
    with ``with_hits`` the obstacle identity per ray (``_UNSET`` where nothing is hit)."""
    n_sensors, n = sensors.shape[0], config.samples
    out = np.full(n_sensors * n, np.inf)
    hits = np.full(n_sensors * n, _UNSET, dtype=np.intp) if with_hits else None
    reach = config.range_max_m + _CULL_SLACK_M
    parts = []
    if rects.shape[0]:
        parts.append(_facing_edges(sensors, rects, exclude, reach, use_grid))
    if segs.shape[0]:
        k_s, m_s, *ends = _near_segments(sensors, segs, reach, use_grid)
        parts.append((k_s, rects.shape[0] + m_s, *ends))
    if not parts:
        return out.reshape(n_sensors, n), _shaped(hits, n_sensors, n)
    k = np.concatenate([p[0] for p in parts])
    ids = np.concatenate([p[1] for p in parts]) if with_hits else None
    wx_a, wy_a, wx_b, wy_b = (np.concatenate([p[i] for p in parts]) for i in range(2, 6))

    # endpoints in the sensor frame
    ch, sh = np.cos(headings)[k], np.sin(headings)[k]
    dx, dy = wx_a - sensors[k, 0], wy_a - sensors[k, 1]
    ax, ay = ch * dx + sh * dy, ch * dy - sh * dx
    dx, dy = wx_b - sensors[k, 0], wy_b - sensors[k, 1]
    bx, by = ch * dx + sh * dy, ch * dy - sh * dx

    # orient each segment counter-clockwise as seen from the sensor: p -> q
    turn = ax * by - ay * bx
    swap = turn < 0.0
    px, py = np.where(swap, bx, ax), np.where(swap, by, ay)
    qx, qy = np.where(swap, ax, bx), np.where(swap, ay, by)
    collinear = turn == 0.0
    touching = collinear & (px * qx + py * qy <= 0.0)  # sensor lies on the segment
    edge_on = collinear & ~touching  # seen exactly end-on: hit only along its line

    # wedge of directions -> run of ray indices (in units of the angle increment)
    inc = config.angle_increment_rad
    u_p = np.mod(np.arctan2(py, px) - config.angle_min_rad, _TWO_PI) / inc
    u_q = np.mod(np.arctan2(qy, qx) - config.angle_min_rad, _TWO_PI) / inc
    near_p = np.hypot(px, py) <= np.hypot(qx, qy)
    u_near = np.where(near_p, u_p, u_q)
    u_p, u_q = np.where(edge_on, u_near, u_p), np.where(edge_on, u_near, u_q)
    first = np.ceil(u_p).astype(np.intp)
    last = np.floor(u_q).astype(np.intp)
    # a wedge never exceeds pi, so u_q far below u_p means it straddles the 2*pi seam;
    # a tiny inversion is rounding on a zero-width wedge and yields an empty run
    wraps = (u_q < u_p) & (u_p - u_q > math.pi / inc) & ~touching

    # per-segment constants of t = num / (dx * e_y - dy * e_x)
    ex, ey = qx - px, qy - py
    num = px * ey - py * ex
    dist_near = np.minimum(np.hypot(px, py), np.hypot(qx, qy))
    unit_x = np.where(near_p, px, qx) / np.where(dist_near > 0.0, dist_near, 1.0)
    unit_y = np.where(near_p, py, qy) / np.where(dist_near > 0.0, dist_near, 1.0)
    num = np.where(edge_on, dist_near, num)
    ex, ey = np.where(edge_on, -unit_y, ex), np.where(edge_on, unit_x, ey)

    live = ~touching
    run_first = first[live]
    run_last = np.where(wraps, n - 1, np.minimum(last, n - 1))[live]
    seg = np.flatnonzero(live)
    wrapped = np.flatnonzero(wraps & live)
    run_first = np.concatenate((run_first, np.zeros(wrapped.size, dtype=np.intp)))
    run_last = np.concatenate((run_last, np.minimum(last[wrapped], n - 1)))
    seg = np.concatenate((seg, wrapped))
    counts = run_last - run_first + 1
    has_rows = counts > 0
    run_first, counts, seg = run_first[has_rows], counts[has_rows], seg[has_rows]

    _evaluate_runs(
        out,
        config,
        k[seg],
        run_first,
        counts,
        num[seg],
        ex[seg],
        ey[seg],
        hits,
        None if ids is None else ids[seg],
    )
    if touching.any():
        on = np.unique(k[touching])
        if hits is not None and ids is not None:  # every ray: the lowest touched obstacle
            touched = np.full(n_sensors, _UNSET, dtype=np.intp)
            np.minimum.at(touched, k[touching], ids[touching])
            hits.reshape(n_sensors, n)[on] = touched[on, None]
        out.reshape(n_sensors, n)[on] = 0.0
    return out.reshape(n_sensors, n), _shaped(hits, n_sensors, n)


def _shaped(hits: IntArray | None, n_sensors: int, n: int) -> IntArray | None:
    return None if hits is None else hits.reshape(n_sensors, n)


def _evaluate_runs(
    out: FloatArray,
    config: LaserConfig,
    sensor: IntArray,
    run_first: IntArray,
    counts: IntArray,
    num: FloatArray,
    ex: FloatArray,
    ey: FloatArray,
    hits: IntArray | None = None,
    ids: IntArray | None = None,
) -> None:
    """For every run (a segment and the consecutive rays that hit it) write the hit
    distances into ``out`` (flat, sensor-major), keeping the minimum per ray; with
    ``hits`` and ``ids`` (the obstacle of each run) also the lowest identity among the
    runs at that minimum (compiled: ``kernels.raycast.evaluate_runs``)."""
    if counts.size == 0:
        return
    angles = config.angles_rad
    with_hits = hits is not None and ids is not None
    evaluate_runs(
        out,
        hits if hits is not None else np.empty(0, dtype=np.intp),
        with_hits,
        (sensor * config.samples + run_first).astype(np.intp),
        run_first.astype(np.intp),
        counts.astype(np.intp),
        np.ascontiguousarray(num, dtype=np.float64),
        np.ascontiguousarray(ex, dtype=np.float64),
        np.ascontiguousarray(ey, dtype=np.float64),
        ids.astype(np.intp) if ids is not None else np.empty(0, dtype=np.intp),
        np.cos(angles),
        np.sin(angles),
        int(_UNSET),
    )
