"""The ray caster as it was in numpy, before the compiled kernels, kept as their oracle.

- ``evaluate_runs`` / ``min_with_identity``: the run evaluation in numpy (the oracle of
  ``platoon_sumo.kernels.raycast.evaluate_runs``): the same minimum per ray and the same
  lowest identity at it, evaluated in chunks of rows.
- ``scan_many``: the whole numpy pipeline of ``platoon_sumo.sensors.raycast.scan_many``
  before ``kernels.raycast.candidate_edges`` / ``evaluate_edges`` replaced it (the grid
  of near pairs, the facing edges, the free segments near each sensor, the wedges' runs
  of rays), with the run evaluation of ``evaluate_runs`` above by default or any other
  with its signature.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from platoon_sumo.geometry import rectangle_corners
from platoon_sumo.kernels.raycast import END_ON_SINE
from platoon_sumo.sensors.laser import LaserConfig
from platoon_sumo.sensors.raycast import (
    _CULL_SLACK_M,
    FloatArray,
    IntArray,
    _finish,
    _no_return,
    obstacle_arrays,
)

_ROWS_PER_CHUNK = 1 << 16
_UNSET = np.iinfo(np.intp).max


def evaluate_runs(
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
    runs at that minimum."""
    if counts.size == 0:
        return
    n = config.samples
    n_sensors = out.size // n
    angles = config.angles_rad
    cos_all = np.tile(np.cos(angles), n_sensors)
    sin_all = np.tile(np.sin(angles), n_sensors)
    flat_first = sensor * n + run_first
    ends = np.cumsum(counts)
    starts = ends - counts
    lane = np.arange(min(int(ends[-1]), _ROWS_PER_CHUNK + int(counts.max())), dtype=np.intp)
    seen = np.zeros(n_sensors, dtype=bool)  # sensors with rows in an earlier chunk
    lo = 0
    while lo < counts.size:
        # runs [lo, hi) hold at most _ROWS_PER_CHUNK rows (or a single larger run)
        hi = int(np.searchsorted(ends, starts[lo] + _ROWS_PER_CHUNK, side="right"))
        hi = max(hi, lo + 1)
        c = counts[lo:hi]
        total = int(ends[hi - 1] - starts[lo])
        flat = lane[:total] - np.repeat(starts[lo:hi] - starts[lo] - flat_first[lo:hi], c)
        denom = cos_all.take(flat) * np.repeat(ey[lo:hi], c)
        denom -= sin_all.take(flat) * np.repeat(ex[lo:hi], c)
        t = np.repeat(num[lo:hi], c)
        t /= denom
        if hits is None or ids is None:
            np.minimum.at(out, flat, t)
        else:
            # only rays of sensors met in an earlier chunk can already hold an identity
            old = seen[sensor[lo:hi]]
            seen[sensor[lo:hi]] = True
            recheck = np.flatnonzero(np.repeat(old, c)) if old.any() else None
            min_with_identity(out, hits, flat, t, np.repeat(ids[lo:hi], c), recheck)
        lo = hi


def min_with_identity(
    out: FloatArray,
    hits: IntArray,
    flat: IntArray,
    t: FloatArray,
    ids: IntArray,
    recheck: IntArray | None,
) -> None:
    """``minimum.at(out, flat, t)``, and in ``hits`` the lowest ``ids`` at each minimum.

    ``recheck``: the rows whose ray may hold an identity from an earlier chunk (None:
    every ray of these rows is still ``_UNSET``). ``ids`` is overwritten.
    """
    before = None if recheck is None else out.take(flat[recheck])
    np.minimum.at(out, flat, t)
    win = t == out.take(flat)
    if recheck is not None and before is not None:
        # a ray whose minimum dropped here forgets the identity of its old minimum
        dropped = recheck[t[recheck] < before]
        hits[flat[dropped]] = _UNSET
    np.putmask(ids, ~win, _UNSET)
    np.minimum.at(hits, flat, ids)


Evaluator = Callable[..., None]
"""``evaluate_runs(out, config, sensor, run_first, counts, num, ex, ey, hits, ids)``."""

_TWO_PI = 2.0 * math.pi


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
    use_grid: bool = True,
    evaluate: Evaluator | None = None,
) -> FloatArray | tuple[FloatArray, IntArray]:
    """The previous ``raycast.scan_many`` (``use_grid=False``: its ``cast_rays`` path,
    every sensor against every obstacle)."""
    pos = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    head = np.asarray(headings, dtype=np.float64).reshape(-1)
    excl = None if exclude is None else np.asarray(exclude, dtype=np.intp).reshape(-1)
    rects, segs = obstacle_arrays(rectangles, segments)
    raw, hits = _raw_ranges(
        pos, head, config, rects, segs, excl, use_grid, return_hits, evaluate or evaluate_runs
    )
    ranges = _finish(raw, config, rng)
    if hits is None:
        return ranges
    return ranges, _no_return(hits, ranges)


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
    with_hits: bool,
    evaluate: Evaluator,
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
    square = (ax * ax + ay * ay) * (bx * bx + by * by)
    collinear = turn * turn <= END_ON_SINE * END_ON_SINE * square  # to rounding
    touching = collinear & (px * qx + py * qy <= 0.0)  # sensor lies on the segment
    edge_on = collinear & ~touching  # seen end-on: hit only along its line

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

    evaluate(
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
