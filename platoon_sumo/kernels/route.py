"""Route kernels: a pruned window projection, the lane request and one whole
route-following step (projection, speed profile, pure pursuit, lane request).

The arithmetic is that of ``platoon_sumo.path.RoutePath`` (``project``, ``point_at``,
``heading_at``, ``lane_step``), ``platoon_sumo.kernels.path`` (``project_kernel``,
``profile_speed_kernel``) and of the Python step of ``RouteFollowing`` they replaced
(``tests/control/reference_route_following.py``), operation by operation. Python's
two-argument ``min`` / ``max`` (keep the first unless the second is smaller / larger,
which decides what a NaN gives) are ``_pmin`` / ``_pmax``. Where the Python code would
raise (a NaN or infinite value turned into an index) the kernels return a status
instead and the caller raises.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from platoon_sumo.kernels.path import (
    project_kernel,
    projection_at,
    segment_d2,
    window_segments,
)

BLOCK = 16
"""Segments per bounding circle of ``path_blocks``."""

STEP_OK = 0
STEP_NOT_FINITE = 1
STEP_LANE_UNREAD = 2
"""``route_step_kernel``'s status: done; nothing computed (a NaN or infinite pose, hint
or preview); or done but for the lane request, which the caller asks the path
(``RoutePath.lane_step``: lane ids the kernel cannot read as numbers)."""


@njit(cache=True)
def _pmin(a: float, b: float) -> float:
    """Python's ``min(a, b)``: ``a`` unless ``b < a``."""
    return b if b < a else a


@njit(cache=True)
def _pmax(a: float, b: float) -> float:
    """Python's ``max(a, b)``: ``a`` unless ``b > a``."""
    return b if b > a else a


def path_blocks(xy: np.ndarray) -> np.ndarray:
    """Bounding circles of the polyline ``xy`` (n, 2) per ``BLOCK`` segments: row b
    (centre x, centre y, radius) holds vertices ``b * BLOCK .. (b + 1) * BLOCK``
    (so every point of those segments). The radius is widened by a hair so that a
    rounded distance never undercuts it. An empty (0, 3) array when ``xy`` holds a
    non-finite or huge value (``project_pruned`` then searches every segment)."""
    xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
    n_seg = max(len(xy) - 1, 0)
    if n_seg == 0 or not (np.abs(xy) < 1e100).all():  # NaN, infinite or overflowing
        return np.zeros((0, 3))
    n_blocks = (n_seg + BLOCK - 1) // BLOCK
    out = np.zeros((n_blocks, 3))
    for b in range(n_blocks):
        pts = xy[b * BLOCK : min((b + 1) * BLOCK, n_seg) + 1]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = 0.5 * (lo + hi)
        radius = float(np.sqrt(((pts - centre) ** 2).sum(axis=1)).max())
        out[b, 0], out[b, 1] = centre
        out[b, 2] = radius * (1.0 + 1e-12) + 1e-9
    return out


@njit(cache=True)
def project_pruned(
    xy: np.ndarray,
    blocks: np.ndarray,
    widths: np.ndarray,
    spacing: float,
    length: float,
    use_hint: bool,
    s_hint: float,
    window: float,
    x: float,
    y: float,
) -> tuple[float, float, float]:
    """``project_kernel``'s result (bit for bit) from fewer segments: the block of
    ``BLOCK`` segments at the hint (without a hint, the block whose circle is nearest)
    is searched first, then every other block of the window whose bounding circle
    (``blocks``, ``path_blocks``) is not farther than the best distance so far (plus a
    micrometre). Of equally near segments the first still wins. A non-finite point or
    path (no blocks) searches every segment (``project_kernel``)."""
    n_seg = xy.shape[0] - 1
    n_blocks = blocks.shape[0]
    if n_blocks == 0 or n_blocks * BLOCK < n_seg or not (abs(x) < 1e100 and abs(y) < 1e100):
        # (a NaN or infinite point, or one so far away that its squares overflow)
        return project_kernel(xy, widths, spacing, length, use_hint, s_hint, window, x, y)
    lo, hi, centre = window_segments(n_seg, spacing, use_hint, s_hint, window)
    b_lo = lo // BLOCK
    b_hi = (hi - 1) // BLOCK + 1
    if use_hint:
        first = centre // BLOCK
    else:
        first = b_lo
        nearest = np.inf
        for b in range(b_lo, b_hi):
            gap = math.hypot(blocks[b, 0] - x, blocks[b, 1] - y) - blocks[b, 2]
            if gap < nearest:
                nearest = gap
                first = b
    margin = 1e-6 + 1e-12 * (abs(x) + abs(y))
    best = np.inf
    best_k = lo
    bound = np.inf  # sqrt(best) + margin
    for step in range(b_hi - b_lo + 1):
        if step == 0:
            b = first
        else:
            b = b_lo + step - 1
            if b == first:
                continue
            gap = math.hypot(blocks[b, 0] - x, blocks[b, 1] - y) - blocks[b, 2]
            if gap > bound:
                continue
        k0 = max(lo, b * BLOCK)
        k1 = min(hi, (b + 1) * BLOCK)
        for k in range(k0, k1):
            d2, _, _ = segment_d2(xy, k, x, y)
            if d2 < best or (d2 == best and k < best_k):
                best = d2
                best_k = k
                bound = math.sqrt(best) + margin
    _, best_t, best_len2 = segment_d2(xy, best_k, x, y)
    return projection_at(xy, widths, spacing, length, x, y, best_k, best_t, best_len2, best)


@njit(cache=True)
def profile_speed_pruned(
    curve_speed: np.ndarray,
    i0: int,
    i1: int,
    spacing: float,
    front_offset: float,
    decel: float,
    v_max: float,
    curve_nan: bool,
) -> float:
    """``profile_speed_kernel``'s result (bit for bit), stopping once the braking distance
    alone (``sqrt(2 decel dist)``, a lower bound of every later point's reachable speed,
    as the distance only grows) exceeds the best speed so far. ``curve_nan``: some
    ``curve_speed`` is NaN (then every point is looked at, as a NaN ahead wins)."""
    best = v_max
    bound = best * best * (1.0 + 1e-9)
    two_b = 2 * decel
    for k in range(i1 - i0):
        limit = curve_speed[i0 + k]
        dist = max(k * spacing - front_offset, 0.0)
        braking = two_b * dist
        if braking > bound and spacing > 0.0 and not curve_nan:
            break
        allowed = math.sqrt(limit * limit + braking)
        if allowed < best or allowed != allowed:
            best = allowed
            if allowed != allowed:
                break
            bound = best * best * (1.0 + 1e-9)
    return best


@njit(cache=True)
def _lane_beside(
    codes: np.ndarray, widths: np.ndarray, shift: np.ndarray, spacing: float, s: float,
    offset: float,
) -> tuple[int, int]:  # fmt: skip
    """(edge number, lane index) of the point `offset` beside the path at `s`, in lane
    widths from the lane there, plus ``shift`` at that point when given (no rows: none);
    edge -1 in a junction, -2 where the Python code would raise (a NaN or infinite arc
    length, a lane width of 0, a lane count that does not fit an integer)."""
    m = _pmax(s, 0.0)
    if not math.isfinite(m):
        return -2, 0
    i = min(int(m // spacing), codes.shape[0] - 1)
    edge = codes[i, 0]
    if edge < 0:
        return -1, 0
    if widths[i] == 0.0:
        return -2, 0
    lanes = offset / widths[i]
    if shift.shape[0]:
        lanes += shift[i]
    if not abs(lanes) < 1e15:
        return -2, 0
    return edge, codes[i, 1] + round(lanes)


_NO_SHIFT = np.zeros(0)


@njit(cache=True)
def lane_step_kernel(
    codes: np.ndarray,
    widths: np.ndarray,
    spans: np.ndarray,
    spacing: float,
    s: float,
    offset: float,
    target_s: float,
    target_offset: float,
) -> int:
    """``RoutePath.lane_step`` on arrays: ``codes`` (n, 2) holds per path point the
    edge's number (-1: a junction lane) and the lane's index, ``spans`` (m, 2) the lane
    changes' (begin, end). -2 where the Python code would raise (a NaN or infinite arc
    length or lane count)."""
    for c in range(spans.shape[0]):
        begin = spans[c, 0]
        end = spans[c, 1]
        if (begin <= s and s <= end) or (begin <= target_s and target_s <= end):
            return 0
    own_edge, own_lane = _lane_beside(codes, widths, _NO_SHIFT, spacing, s, offset)
    if own_edge < 0:
        return own_edge if own_edge == -2 else 0
    edge, lane = _lane_beside(codes, widths, _NO_SHIFT, spacing, target_s, target_offset)
    if edge < 0:
        return edge if edge == -2 else 0
    if own_edge != edge or own_lane == lane:
        return 0
    return 1 if lane > own_lane else -1


@njit(cache=True)
def same_lane_kernel(
    codes: np.ndarray,
    widths: np.ndarray,
    shift: np.ndarray,
    spacing: float,
    s: float,
    offset: float,
    target_s: float,
    target_offset: float,
) -> int:
    """``RoutePath.same_lane`` on arrays (``codes``, ``widths`` as for
    ``lane_step_kernel``, ``shift`` per point: ``RoutePath._lane_shift``): 1 or 0, -2
    where the Python code would raise."""
    finite = math.isfinite(s) and math.isfinite(offset)
    if not (finite and math.isfinite(target_s) and math.isfinite(target_offset)):
        return 0
    own_edge, own_lane = _lane_beside(codes, widths, shift, spacing, s, offset)
    if own_edge < 0:
        return own_edge if own_edge == -2 else 0
    edge, lane = _lane_beside(codes, widths, shift, spacing, target_s, target_offset)
    if edge == -2:
        return -2
    return 1 if edge == own_edge and lane == own_lane else 0


@njit(cache=True)
def _point_at(xy: np.ndarray, spacing: float, length: float, last_step: float, s_m: float):
    """``RoutePath.point_at``."""
    s = _pmin(_pmax(s_m, 0.0), length)
    last = xy.shape[0] - 2
    i = int(_pmin(s // spacing, last))
    step = spacing if i < last else last_step
    t = (s - i * spacing) / step if step > 0 else 0.0
    t = _pmin(_pmax(t, 0.0), 1.0)
    x0 = xy[i, 0]
    y0 = xy[i, 1]
    return x0 + (xy[i + 1, 0] - x0) * t, y0 + (xy[i + 1, 1] - y0) * t


@njit(cache=True)
def _heading_at(xy: np.ndarray, spacing: float, length: float, s_m: float) -> float:
    """``RoutePath.heading_at``."""
    s = _pmin(_pmax(s_m, 0.0), length)
    i = int(_pmin(_pmax(s // spacing, 0.0), xy.shape[0] - 2))
    return math.atan2(xy[i + 1, 1] - xy[i, 1], xy[i + 1, 0] - xy[i, 0])


PARAM_NAMES = (
    "lookahead_min_m",
    "lookahead_time_s",
    "comfort_decel_mps2",
    "max_speed_mps",
    "max_decel_mps2",
    "max_accel_mps2",
)
"""The entries of ``route_step_kernel``'s ``params``: the controller's look-ahead and
comfort deceleration, the vehicle's limits."""


@njit(cache=True)
def route_step_kernel(
    xy: np.ndarray,
    blocks: np.ndarray,
    widths: np.ndarray,
    codes: np.ndarray,
    spans: np.ndarray,
    geometry: np.ndarray,
    curve_speed: np.ndarray,
    curve_nan: bool,
    params: np.ndarray,
    s_hint: float,
    x: float,
    y: float,
    yaw: float,
    speed: float,
    front_offset: float,
    vehicle_length: float,
    dt: float,
    lane_offset: float,
    signal_limit: float,
    following_limit: float,
) -> tuple[int, float, float, float, int]:
    """One ``RouteFollowing.step`` after its signal and vehicle-ahead limits: the arc
    length on the path (projection near ``s_hint``), the speed profile ahead, the pure
    pursuit of the point one look-ahead on (beside the path by ``lane_offset``) and the
    lane request. ``geometry`` is the path's (spacing, length, last step); ``codes`` and
    ``spans`` as for ``lane_step_kernel`` (``codes`` with no rows: lane ids the kernel
    cannot read; the caller asks the path for the lane request); ``params`` as
    ``PARAM_NAMES``.
    Returns (status, arc length, speed, yaw rate, lane request), status as ``STEP_OK``."""
    spacing = geometry[0]
    length = geometry[1]
    last_step = geometry[2]
    look_min = params[0]
    look_time = params[1]
    decel = params[2]
    max_speed = params[3]
    max_decel = params[4]
    max_accel = params[5]
    lookahead = _pmax(look_min, look_time * speed)
    window = _pmax(20.0, 3 * lookahead)
    if not (math.isfinite(s_hint) and window >= 0.0 and window < math.inf):
        return STEP_NOT_FINITE, 0.0, 0.0, 0.0, 0
    if math.isnan(lane_offset) or math.isinf(lane_offset):
        return STEP_NOT_FINITE, 0.0, 0.0, 0.0, 0
    s, _, _ = project_pruned(xy, blocks, widths, spacing, length, True, s_hint, window, x, y)
    # the speed profile ahead (RouteFollowing._profile_speed)
    v_max = _pmax(max_speed, speed)
    preview = v_max**2 / (2 * decel) + 2 * vehicle_length
    q0 = s // spacing
    q1 = preview / spacing
    if not (math.isfinite(q0) and math.isfinite(q1) and abs(q0) < 1e15 and abs(q1) < 1e15):
        return STEP_NOT_FINITE, 0.0, 0.0, 0.0, 0
    i0 = int(q0)
    i1 = min(xy.shape[0], i0 + int(q1) + 2)
    i0 = min(max(i0, 0), i1)
    reachable = profile_speed_pruned(
        curve_speed, i0, i1, spacing, front_offset, decel, v_max, curve_nan
    )
    cmd_speed = _pmin(_pmin(_pmin(reachable, max_speed), signal_limit), following_limit)
    # pure pursuit on the speed the vehicle model will reach
    next_speed = _pmin(_pmax(cmd_speed, speed - max_decel * dt), speed + max_accel * dt)
    ahead = s + lookahead
    if not math.isfinite(ahead):
        return STEP_NOT_FINITE, 0.0, 0.0, 0.0, 0
    tx, ty = _point_at(xy, spacing, length, last_step, ahead)
    if lane_offset != 0.0:
        heading = _heading_at(xy, spacing, length, ahead)
        tx -= lane_offset * math.sin(heading)
        ty += lane_offset * math.cos(heading)
    dx = tx - x
    dy = ty - y
    dist = math.hypot(dx, dy)
    alpha = math.atan2(dy, dx) - yaw
    curvature = 2.0 * math.sin(alpha) / dist if dist > 1e-6 else 0.0
    yaw_rate = _pmax(next_speed, 0.0) * curvature
    lane = 0
    if lane_offset != 0.0:
        if codes.shape[0] == 0:
            return STEP_LANE_UNREAD, s, cmd_speed, yaw_rate, 0
        lane = lane_step_kernel(codes, widths, spans, spacing, s, lane_offset, s, 0.0)
        if lane == -2:
            return STEP_LANE_UNREAD, s, cmd_speed, yaw_rate, 0
    return STEP_OK, s, cmd_speed, yaw_rate, lane


ROUTE_INPUT_NAMES = (
    "s_hint_m", "x_m", "y_m", "yaw_rad", "speed_mps", "front_offset_m", "length_m",
    "dt_s", "lane_offset_m", "signal_limit_mps", "following_limit_mps", *PARAM_NAMES,
)  # fmt: skip
"""The columns of ``route_batch_kernel``'s ``inputs``: ``route_step_kernel``'s scalars
from ``s_hint`` on, then its ``params``."""


@njit(cache=True)
def route_batch_kernel(
    xy: np.ndarray,
    xy_starts: np.ndarray,
    blocks: np.ndarray,
    block_starts: np.ndarray,
    widths: np.ndarray,
    codes: np.ndarray,
    code_starts: np.ndarray,
    spans: np.ndarray,
    span_starts: np.ndarray,
    curve: np.ndarray,
    curve_starts: np.ndarray,
    geometry: np.ndarray,
    path_of: np.ndarray,
    inputs: np.ndarray,
) -> np.ndarray:
    """``route_step_kernel`` for many vehicles in one call. Vehicle j is on entry
    ``p = path_of[j]``: its path's points and lane widths are rows
    ``xy_starts[p]:xy_starts[p + 1]`` of ``xy`` and ``widths``, its blocks, lane codes,
    lane-change spans and curve speeds the rows of ``blocks``, ``codes``, ``spans`` and
    ``curve`` between their starts, row p of ``geometry`` (spacing, length, last step, whether a
    curve speed is NaN); it reads ``inputs[j]`` (``ROUTE_INPUT_NAMES``). Row j of the
    result is its (status, arc length, speed, yaw rate, lane request)."""
    n = path_of.shape[0]
    out = np.empty((n, 5))
    for j in range(n):
        p = path_of[j]
        a = xy_starts[p]
        b = xy_starts[p + 1]
        v = inputs[j]
        g = geometry[p]
        status, s, speed, yaw_rate, lane = route_step_kernel(
            xy[a:b], blocks[block_starts[p] : block_starts[p + 1]], widths[a:b],
            codes[code_starts[p] : code_starts[p + 1]], spans[span_starts[p] : span_starts[p + 1]],
            g[:3], curve[curve_starts[p] : curve_starts[p + 1]], g[3] != 0.0, v[11:], v[0],
            v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9], v[10],
        )  # fmt: skip
        out[j, 0] = status
        out[j, 1] = s
        out[j, 2] = speed
        out[j, 3] = yaw_rate
        out[j, 4] = lane
    return out


@njit(cache=True)
def project_members(
    xy: np.ndarray,
    xy_starts: np.ndarray,
    blocks: np.ndarray,
    block_starts: np.ndarray,
    widths: np.ndarray,
    geometry: np.ndarray,
    path_of: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    s_hint: np.ndarray,
    window: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``project_pruned`` with a hint for every member at once: member k on path
    ``path_of[k]``, whose points and lane widths are rows ``xy_starts[p]:xy_starts[p + 1]``
    of ``xy`` and ``widths``, blocks rows ``block_starts[p]:block_starts[p + 1]`` of
    ``blocks``, (spacing, length) row p of ``geometry``. Returns (arc lengths, lateral
    offsets)."""
    n = path_of.shape[0]
    s_out = np.empty(n)
    lateral_out = np.empty(n)
    for k in range(n):
        p = path_of[k]
        a = xy_starts[p]
        b = xy_starts[p + 1]
        s, lateral, _ = project_pruned(
            xy[a:b], blocks[block_starts[p] : block_starts[p + 1]], widths[a:b],
            geometry[p, 0], geometry[p, 1], True, s_hint[k], window[k], x[k], y[k],
        )  # fmt: skip
        s_out[k] = s
        lateral_out[k] = lateral
    return s_out, lateral_out
