"""Ray-casting kernels of ``platoon_sumo.sensors.raycast``: a batch of scans in two
compiled passes.

1. ``candidate_edges``: per sensor, the rectangle edges that face it and the free
   segments within reach (a hashed grid built once per call gives each sensor the
   obstacles near it), each turned into the sensor's frame and oriented
   counter-clockwise (``p -> q``), with the constants of its hit distance; a sensor
   lying on a surface is noted instead.
2. Between the passes numpy takes the bearings of the edges' ends (``arctan2``), so
   they are numpy's bit for bit: its SIMD ``arctan2`` and libm's differ in the last bit
   now and then, and that bit decides whether a ray through a corner belongs to an edge.
3. ``evaluate_edges``: per sensor, the run of rays each edge's wedge covers and the hit
   distance of each of those rays, the minimum per ray and the lowest identity at it,
   then the REP 117 readings and the identities of the row while it is in cache.

The arithmetic, operation by operation, is that of the numpy implementation they
replace (kept in ``tests/sensors/reference_raycast.py`` as their oracle). The kernels
use numpy's error model: a division by zero (a ray parallel to an edge, in degenerate
scenes) gives an infinity or a NaN, as in numpy, instead of raising.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Rows of the edges' float table (one column per edge): the ends ``p``, ``q`` in the
#: sensor frame, the constants of the hit distance, and the ends' bearings (numpy's).
GEO_ROWS = ("px", "py", "qx", "qy", "num", "ex", "ey", "bearing_p", "bearing_q")
#: Rows of the edges' integer table: the obstacle's identity and the kind of edge.
INT_ROWS = ("ident", "kind")
#: Kinds of edge: seen as a wedge; seen end-on (hit only along its line), its ``p``
#: end nearer or its ``q`` end nearer.
WEDGE, END_ON_P, END_ON_Q = 0, 1, 2
#: An edge whose ends are less than this far apart in bearing, seen from the sensor
#: [rad] (the sine; squared below), is seen end-on: the distance along a ray between
#: its ends' bearings divides two numbers that are rounding only, and once put a wall
#: lying along a ray 0.9 m nearer than its near end (found by the hypothesis oracle).
END_ON_SINE = 1e-12
_END_ON_SINE2 = END_ON_SINE * END_ON_SINE
#: Relative band around the reach in which the squared-distance test defers to
#: ``math.hypot`` (the numpy implementation's test), far wider than their rounding.
_BAND = 1e-9


@njit(cache=True, error_model="numpy")
def _evaluate_run(
    out: np.ndarray,
    hits: np.ndarray,
    with_hits: bool,
    base: int,
    ray0: int,
    count: int,
    nu: float,
    e_x: float,
    e_y: float,
    ident: int,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
) -> None:
    """One run: rays ``ray0 .. ray0 + count - 1`` at flat positions ``base ..`` of
    ``out``: distance ``nu / (cos * e_y - sin * e_x)`` kept where smaller (a NaN poisons
    the ray, as ``np.minimum`` does; its hit stays), ``ident`` kept in ``hits`` where it
    is the lowest at the ray's minimum."""
    for j in range(count):
        flat = base + j
        ray = ray0 + j
        denom = cos_a[ray] * e_y
        denom -= sin_a[ray] * e_x
        t = nu / denom
        old = out[flat]
        if t < old:
            out[flat] = t
            if with_hits:
                hits[flat] = ident
        elif t == old:
            if with_hits and ident < hits[flat]:
                hits[flat] = ident
        elif t != t and old == old:  # a NaN distance poisons the ray (its hit stays)
            out[flat] = t


@njit(cache=True, error_model="numpy")
def _within(gx: float, gy: float, reach: float) -> bool:
    """``math.hypot(gx, gy) <= reach``, decided by the squares away from the boundary."""
    g2 = gx * gx + gy * gy
    r2 = reach * reach
    if g2 < r2 * (1.0 - _BAND):
        return True
    if g2 > r2 * (1.0 + _BAND):
        return False
    return math.hypot(gx, gy) <= reach


@njit(cache=True, error_model="numpy")
def _cell_hash(gx: int, gy: int, mask: int) -> int:
    return ((gx * 73856093) ^ (gy * 19349663)) & mask


@njit(cache=True, error_model="numpy")
def _build_grid(
    rects: np.ndarray, segs: np.ndarray, cell: float
) -> tuple[np.ndarray, np.ndarray, int]:
    """A hashed uniform grid of square cells of side ``cell``: a rectangle is listed in
    the cell of its centre, a segment in every cell of its bounding box, each under the
    hash of its cell (objects numbered rectangles first, then segments). Returns the
    bucket starts (``mask + 2``), the objects bucket by bucket, and the hash mask."""
    n_rect = rects.shape[0]
    n_seg = segs.shape[0]
    total = n_rect
    for j in range(n_seg):
        x0 = math.floor(min(segs[j, 0], segs[j, 2]) / cell)
        x1 = math.floor(max(segs[j, 0], segs[j, 2]) / cell)
        y0 = math.floor(min(segs[j, 1], segs[j, 3]) / cell)
        y1 = math.floor(max(segs[j, 1], segs[j, 3]) / cell)
        total += (x1 - x0 + 1) * (y1 - y0 + 1)
    size = 16
    while size < 2 * total:
        size *= 2
    mask = size - 1
    entry_obj = np.empty(total, np.int64)
    entry_hash = np.empty(total, np.int64)
    for i in range(n_rect):
        entry_obj[i] = i
        gx = math.floor(rects[i, 0] / cell)
        gy = math.floor(rects[i, 1] / cell)
        entry_hash[i] = _cell_hash(gx, gy, mask)
    m = n_rect
    for j in range(n_seg):
        x0 = math.floor(min(segs[j, 0], segs[j, 2]) / cell)
        x1 = math.floor(max(segs[j, 0], segs[j, 2]) / cell)
        y0 = math.floor(min(segs[j, 1], segs[j, 3]) / cell)
        y1 = math.floor(max(segs[j, 1], segs[j, 3]) / cell)
        for gx in range(x0, x1 + 1):
            for gy in range(y0, y1 + 1):
                entry_obj[m] = n_rect + j
                entry_hash[m] = _cell_hash(gx, gy, mask)
                m += 1
    # counting sort of the entries by bucket
    head = np.zeros(size + 1, np.int64)
    for m in range(total):
        head[entry_hash[m] + 1] += 1
    for h in range(size):
        head[h + 1] += head[h]
    fill = np.empty(size, np.int64)
    for h in range(size):
        fill[h] = head[h]
    objs = np.empty(total, np.int64)
    for m in range(total):
        h = entry_hash[m]
        objs[fill[h]] = entry_obj[m]
        fill[h] += 1
    return head, objs, mask


@njit(cache=True, error_model="numpy")
def _grow(geo: np.ndarray, ints: np.ndarray, used: int) -> tuple[np.ndarray, np.ndarray]:
    """Tables of twice the columns (at least 64), the first ``used`` copied."""
    cap = max(2 * geo.shape[1], 64)
    new_geo = np.empty((geo.shape[0], cap))
    new_ints = np.empty((ints.shape[0], cap), np.int64)
    for r in range(geo.shape[0]):
        for c in range(used):
            new_geo[r, c] = geo[r, c]
    for r in range(ints.shape[0]):
        for c in range(used):
            new_ints[r, c] = ints[r, c]
    return new_geo, new_ints


@njit(cache=True, error_model="numpy", inline="always")
def _put(
    geo: np.ndarray,
    ints: np.ndarray,
    e: int,
    ident: int,
    ax: float,
    ay: float,
    bx: float,
    by: float,
) -> int:
    """Edge (a, b), world frame, of obstacle ``ident`` into column ``e``; the next one."""
    geo[0, e] = ax
    geo[1, e] = ay
    geo[2, e] = bx
    geo[3, e] = by
    ints[0, e] = ident
    return e + 1


@njit(cache=True, error_model="numpy")
def candidate_edges(
    sensors: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    rects: np.ndarray,
    cos_yaw: np.ndarray,
    sin_yaw: np.ndarray,
    segs: np.ndarray,
    exclude: np.ndarray,
    reach: float,
    use_grid: bool,
    unset: int,
    geo: np.ndarray,
    ints: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The edges each of the K ``sensors`` (heading cosines / sines ``cos_h``, ``sin_h``)
    must test: the edges of ``rects`` (N, 5) that face it (all 4 if it is inside), but
    not those of rectangle ``exclude[k]``, of the rectangles that come within ``reach``
    of it, and the ``segs`` (M, 4) within ``reach``. ``cos_yaw`` / ``sin_yaw`` are the
    rectangles'; ``use_grid=False`` tests every sensor against every obstacle.

    ``geo`` (``GEO_ROWS``, C) and ``ints`` (``INT_ROWS``, C) are the tables to fill, of
    any number of columns (they are replaced by larger ones when full). Returns

    - ``starts`` (K + 1): sensor k's edges are columns ``starts[k]:starts[k + 1]``;
    - ``touch`` (K): the lowest identity of a surface sensor k lies on (it reads 0 on
      every ray), ``unset`` if none; the edges it lies on are not listed;
    - ``geo``: rows ``px`` .. ``ey`` filled: the ends ``p``, ``q`` in the sensor frame,
      counter-clockwise as seen from it, and ``num``, ``ex``, ``ey`` of the hit distance
      ``num / (cos * ey - sin * ex)`` of a ray at angle a (for an end-on edge: the near
      end's distance over the cosine between the ray and its direction);
    - ``ints``: identity (``i`` for ``rects[i]``, ``N + j`` for ``segs[j]``) and kind
      (``WEDGE``, ``END_ON_P``, ``END_ON_Q``) of each edge.

    A rectangle's corners are those of ``geometry.rectangle_corners`` (front-right,
    front-left, rear-left, rear-right), edge e from corner e to corner e + 1.
    """
    k_count = sensors.shape[0]
    n_rect = rects.shape[0]
    n_seg = segs.shape[0]
    n_obj = n_rect + n_seg
    starts = np.zeros(k_count + 1, np.int64)
    touch = np.full(k_count, unset, np.int64)
    if k_count == 0 or n_obj == 0:
        return starts, touch, geo, ints

    max_half_diag = 0.0
    for i in range(n_rect):
        max_half_diag = max(max_half_diag, 0.5 * math.hypot(rects[i, 3], rects[i, 4]))
    # the grid only has to give a superset (the exact tests follow); the margin absorbs
    # the rounding of the cell indices
    margin = 1e-6 * (1.0 + reach)
    cell = 0.5 * (reach + max_half_diag) + margin
    if use_grid:
        head, objs, mask = _build_grid(rects, segs, cell)
    else:
        head = np.zeros(2, np.int64)
        head[1] = n_obj
        objs = np.arange(n_obj)
        mask = 0
    stamp = np.full(n_obj, -1, np.int64)
    blocks = 25 if use_grid else 1
    far = reach + max_half_diag + margin  # no rectangle farther (per axis) can be in reach

    e = 0
    for k in range(k_count):
        sx = sensors[k, 0]
        sy = sensors[k, 1]
        ch = cos_h[k]
        sh = sin_h[k]
        own = exclude[k]
        gx = math.floor(sx / cell) if use_grid else 0
        gy = math.floor(sy / cell) if use_grid else 0
        for b in range(blocks):
            bucket = _cell_hash(gx + b // 5 - 2, gy + b % 5 - 2, mask) if use_grid else 0
            for a in range(head[bucket], head[bucket + 1]):
                o = objs[a]
                if stamp[o] == k:
                    continue
                stamp[o] = k
                if e + 4 > geo.shape[1]:
                    geo, ints = _grow(geo, ints, e)
                if o < n_rect:
                    if o == own:
                        continue
                    # the sensor in the rectangle's own frame; its gap to the rectangle
                    cx = rects[o, 0]
                    cy = rects[o, 1]
                    hl = 0.5 * rects[o, 3]
                    hw = 0.5 * rects[o, 4]
                    dx = sx - cx
                    dy = sy - cy
                    if abs(dx) > far or abs(dy) > far:
                        continue
                    c = cos_yaw[o]
                    s = sin_yaw[o]
                    lx = c * dx + s * dy
                    ly = c * dy - s * dx
                    gap_x = abs(lx) - hl
                    gap_y = abs(ly) - hw
                    if gap_x < 0.0:
                        gap_x = 0.0
                    if gap_y < 0.0:
                        gap_y = 0.0
                    if not _within(gap_x, gap_y, reach):
                        continue
                    f0 = lx >= hl
                    f1 = ly >= hw
                    f2 = lx <= -hl
                    f3 = ly <= -hw
                    inside = not (f0 or f1 or f2 or f3)  # every inner wall counts
                    # corners: front-right, front-left, rear-left, rear-right
                    x0 = cx + c * hl - s * -hw
                    y0 = cy + s * hl + c * -hw
                    x1 = cx + c * hl - s * hw
                    y1 = cy + s * hl + c * hw
                    x2 = cx + c * -hl - s * hw
                    y2 = cy + s * -hl + c * hw
                    x3 = cx + c * -hl - s * -hw
                    y3 = cy + s * -hl + c * -hw
                    if inside or f0:
                        e = _put(geo, ints, e, o, x0, y0, x1, y1)
                    if inside or f1:
                        e = _put(geo, ints, e, o, x1, y1, x2, y2)
                    if inside or f2:
                        e = _put(geo, ints, e, o, x2, y2, x3, y3)
                    if inside or f3:
                        e = _put(geo, ints, e, o, x3, y3, x0, y0)
                else:
                    j = o - n_rect
                    ax = segs[j, 0]
                    ay = segs[j, 1]
                    bx = segs[j, 2]
                    by = segs[j, 3]
                    if (
                        min(ax, bx) - sx > reach + margin
                        or sx - max(ax, bx) > reach + margin
                        or min(ay, by) - sy > reach + margin
                        or sy - max(ay, by) > reach + margin
                    ):
                        continue
                    ex = bx - ax
                    ey = by - ay
                    length2 = ex * ex + ey * ey
                    f = 0.0
                    if length2 > 0.0:
                        f = ((sx - ax) * ex + (sy - ay) * ey) / length2
                        if f < 0.0:
                            f = 0.0
                        elif f > 1.0:
                            f = 1.0
                    if not _within(ax + f * ex - sx, ay + f * ey - sy, reach):
                        continue
                    e = _put(geo, ints, e, o, ax, ay, bx, by)
        # the sensor's edges, world frame -> sensor frame, in place (a sensor lying on
        # an edge drops it and notes it in touch[k])
        w = starts[k]
        for c in range(starts[k], e):
            ident = ints[0, c]
            dx = geo[0, c] - sx
            dy = geo[1, c] - sy
            ax = ch * dx + sh * dy
            ay = ch * dy - sh * dx
            dx = geo[2, c] - sx
            dy = geo[3, c] - sy
            bx = ch * dx + sh * dy
            by = ch * dy - sh * dx
            # orient the segment counter-clockwise as seen from the sensor: p -> q
            turn = ax * by - ay * bx
            square = (ax * ax + ay * ay) * (bx * bx + by * by)
            swap = turn < 0.0
            px = bx if swap else ax
            py = by if swap else ay
            qx = ax if swap else bx
            qy = ay if swap else by
            ex = qx - px
            ey = qy - py
            num = px * ey - py * ex
            kind = WEDGE
            if turn * turn <= _END_ON_SINE2 * square:  # end-on (exactly: turn == 0)
                if px * qx + py * qy <= 0.0:  # the sensor lies on the segment
                    touch[k] = min(touch[k], ident)
                    continue
                # seen end-on: hit only along its line, at its near end
                dist_p = math.hypot(px, py)
                dist_q = math.hypot(qx, qy)
                near_p = dist_p <= dist_q
                dist_near = dist_p if near_p else dist_q
                scale = dist_near if dist_near > 0.0 else 1.0
                unit_x = (px if near_p else qx) / scale
                unit_y = (py if near_p else qy) / scale
                num = dist_near
                ex = -unit_y
                ey = unit_x
                kind = END_ON_P if near_p else END_ON_Q
            geo[0, w] = px
            geo[1, w] = py
            geo[2, w] = qx
            geo[3, w] = qy
            geo[4, w] = num
            geo[5, w] = ex
            geo[6, w] = ey
            ints[0, w] = ident
            ints[1, w] = kind
            w += 1
        e = w
        starts[k + 1] = e
    return starts, touch, geo, ints


# ------------------------------------------------------------------- pass 2: the rays


@njit(cache=True, error_model="numpy")
def _wrapped(bearing: float, angle_min: float, two_pi: float) -> float:
    """``np.mod(bearing - angle_min, two_pi)``, bit for bit (fmod is exact, so for a
    difference already in (-2 pi, 2 pi) it is the difference itself)."""
    x = bearing - angle_min
    if 0.0 < x < two_pi:
        return x
    if -two_pi < x < 0.0:
        return x + two_pi
    return x % two_pi


@njit(cache=True, error_model="numpy")
def evaluate_edges(
    starts: np.ndarray,
    touch: np.ndarray,
    ints: np.ndarray,
    geo: np.ndarray,
    angle_min: float,
    angle_inc: float,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    range_min: float,
    range_max: float,
    out: np.ndarray,
    hits: np.ndarray,
    with_hits: bool,
    unset: int,
    no_return: int,
) -> None:
    """REP 117 readings of the edges of ``candidate_edges`` (their ends' bearings,
    ``arctan2``, in rows ``bearing_p``, ``bearing_q`` of ``geo``) into ``out`` (K,
    samples), and with ``with_hits`` the identity of each reading into ``hits`` (K,
    samples): the lowest identity at the ray's first-hit distance, ``no_return`` where
    the reading is ``+inf`` or ``NaN``.

    An edge covers the rays from ``ceil(u_p)`` to ``floor(u_q)`` (``u``: its ends'
    bearings from ``angle_min`` in [0, 2 pi), in units of ``angle_inc``), wrapping
    around when the wedge straddles the 2 pi seam; an end-on edge only the ray along it.
    A sensor on a surface reads 0 on every ray (``touch``). The raw distance becomes
    REP 117: below 0 is 0 when ``range_min`` is 0 (rounding), beyond ``range_max``
    ``+inf``, below ``range_min`` ``-inf``.
    """
    k_count = starts.shape[0] - 1
    n = cos_a.shape[0]
    two_pi = 2.0 * math.pi
    half_turn = math.pi / angle_inc
    for k in range(k_count):
        row_out = out[k]
        row_hits = hits[k] if with_hits else hits.reshape(-1)[:0]
        lying = touch[k] != unset
        fill = 0.0 if lying else np.inf
        row_out[:] = fill
        if with_hits:
            ident0 = touch[k] if lying else unset
            row_hits[:] = ident0
        if not lying:
            for e in range(starts[k], starts[k + 1]):
                u_p = _wrapped(geo[7, e], angle_min, two_pi) / angle_inc
                u_q = _wrapped(geo[8, e], angle_min, two_pi) / angle_inc
                kind = ints[1, e]
                if kind == END_ON_P:
                    u_q = u_p
                elif kind == END_ON_Q:
                    u_p = u_q
                if not (u_p >= 0.0 and u_q >= 0.0):  # NaN: an edge without a direction
                    continue
                first = math.ceil(u_p)
                last = min(math.floor(u_q), n - 1)
                ident = ints[0, e]
                nu = geo[4, e]
                e_x = geo[5, e]
                e_y = geo[6, e]
                # the run of rays [first, last]; a wedge never exceeds pi, so one that
                # straddles the 2 pi seam is [first, n - 1] and [0, last] (a tiny
                # inversion is rounding on a zero-width wedge: an empty run)
                wraps = u_q < u_p and u_p - u_q > half_turn
                for part in range(2 if wraps else 1):
                    lo = first if part == 0 else 0
                    hi = n - 1 if wraps and part == 0 else last
                    if with_hits:
                        for ray in range(lo, hi + 1):
                            denom = cos_a[ray] * e_y
                            denom -= sin_a[ray] * e_x
                            t = nu / denom
                            old = row_out[ray]
                            h = row_hits[ray]
                            # the smaller distance wins (a NaN poisons the ray, its hit
                            # stays), the lower identity at an equal one
                            row_out[ray] = t if t < old or (t != t and old == old) else old
                            row_hits[ray] = ident if t < old or (t == old and ident < h) else h
                    else:
                        for ray in range(lo, hi + 1):
                            denom = cos_a[ray] * e_y
                            denom -= sin_a[ray] * e_x
                            t = nu / denom
                            old = row_out[ray]
                            row_out[ray] = t if t < old or (t != t and old == old) else old
        # REP 117 (branch-free loops)
        if range_min == 0.0:
            for j in range(n):
                v = row_out[j]
                row_out[j] = 0.0 if v <= 0.0 else v  # rounding: -1e-17 on a touching surface
        for j in range(n):
            v = row_out[j]
            row_out[j] = np.inf if v > range_max else (-np.inf if v < range_min else v)
        if with_hits:
            for j in range(n):  # +inf or NaN: no return
                row_hits[j] = row_hits[j] if row_out[j] < np.inf else no_return
