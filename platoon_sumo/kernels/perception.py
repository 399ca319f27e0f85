"""Perception kernels: scan segmentation and rear fitting over a whole scan in one call
(``detect_into``), and the rear tracker's Kalman step (``kalman_step``).

The algorithms are those of ``platoon_sumo.control.perception`` (see its docstring),
written as loops over the rays and points: the adaptive-breakpoint segmentation (with
the rays' cosines and sines given as tables), the line / L-shape rear fit with
total-least-squares sides (the dominant eigenvector of a 2x2 scatter matrix in closed
form), the end classification, and the constant-velocity Kalman filter's predict, gate
and update written out for its 4 states. A candidate is a row of ``CANDIDATE_COLUMNS``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

CANDIDATE_COLUMNS = ("x", "y", "width", "heading", "complete", "l_shape", "alternative", "lo", "hi")
"""Columns of a candidate row: the rear centre (sensor frame), its visible width, its
heading, three flags (0 / 1) and the cluster's rows ``lo:hi`` of the points array."""
N_COLUMNS = len(CANDIDATE_COLUMNS)

MAX_CORNER_COS = math.cos(math.radians(60.0))
"""The sides of an L-shape must meet at 60 deg or more (90 for a box)."""


@njit(cache=True)
def _segment(
    ranges: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    angle_inc: float,
    break_abs: float,
    lam: float,
    max_dropout_gap: int,
    range_min: float,
    box_x: float,
    box_half: float,
    pts: np.ndarray,
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, bool]:
    """Clusters of a scan (see ``perception.segment_scan``): the hit points are written to
    the first rows of ``pts`` (at least as many rows as rays); returns their number, their
    sample indices, the clusters' start / stop rows, and, found in the same pass, whether
    anything is in the box ``0 < x <= box_x``, ``|y| <= box_half`` ahead of the sensor: a
    hit, or a ``-inf`` reading (closer than ``range_min``, position unknown) whose ray
    could be in it."""
    n = ranges.size
    boxed = False
    idx = np.empty(n, np.int64)
    starts = np.empty(n, np.int64)
    stops = np.empty(n, np.int64)
    abs_inc = abs(angle_inc)
    ratio_1 = math.sin(abs_inc) / max(math.sin(lam - abs_inc), 1e-3)  # next ray: the usual
    m = 0  # hits so far
    nc = 0  # clusters so far
    inf_since = False  # a +-inf reading since the last hit
    for i in range(n):
        r = ranges[i]
        if not abs(r) < np.inf:  # not finite (np.isfinite / isinf are slower in numba)
            if r == r:  # +-inf, not NaN
                inf_since = True
                if r < 0.0 and cos_a[i] > 0.0 and abs(range_min * sin_a[i]) <= box_half:
                    boxed = True
            continue
        x = r * cos_a[i]
        y = r * sin_a[i]
        if x > 0.0 and x <= box_x and abs(y) <= box_half:
            boxed = True
        pts[m, 0] = x
        pts[m, 1] = y
        idx[m] = i
        if m == 0:
            split = True
        else:
            i0 = idx[m - 1]
            gap = i - i0
            if inf_since or gap - 1 > max_dropout_gap:
                split = True
            else:
                dx = x - pts[m - 1, 0]
                dy = y - pts[m - 1, 1]
                step = math.sqrt(dx * dx + dy * dy)  # hypot to rounding, a third of its cost
                if gap == 1:
                    ratio = ratio_1
                else:
                    dphi = gap * abs_inc
                    ratio = math.sin(dphi) / max(math.sin(lam - dphi), 1e-3)
                split = step > break_abs + min(r, ranges[i0]) * ratio
        if split:
            if nc > 0:
                stops[nc - 1] = m
            starts[nc] = m
            nc += 1
        inf_since = False
        m += 1
    if nc > 0:
        stops[nc - 1] = m
    return m, idx[:m], starts[:nc], stops[:nc], boxed


@njit(cache=True)
def segment_kernel(
    ranges: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    angle_inc: float,
    break_abs: float,
    lam: float,
    max_dropout_gap: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Hit points (sensor frame), their sample indices and the clusters' start / stop rows.
    ``cos_a`` / ``sin_a``: cosine and sine of each ray's angle."""
    pts = np.empty((ranges.size, 2))
    m, idx, starts, stops, _ = _segment(
        ranges, cos_a, sin_a, angle_inc, break_abs, lam, max_dropout_gap, 0.0, -1.0, -1.0, pts
    )
    return pts[:m], idx, starts, stops


@njit(cache=True)
def _tls_line(pts: np.ndarray, lo: int, hi: int) -> tuple[float, float, float, float]:
    """Total-least-squares line through rows lo:hi: a point on it and its unit direction."""
    k = hi - lo
    sx = 0.0
    sy = 0.0
    for q in range(lo, hi):
        sx += pts[q, 0]
        sy += pts[q, 1]
    cx = sx / k
    cy = sy / k
    a = 0.0
    b = 0.0
    c = 0.0
    for q in range(lo, hi):
        dx = pts[q, 0] - cx
        dy = pts[q, 1] - cy
        a += dx * dx
        b += dx * dy
        c += dy * dy
    # eigenvector of [[a, b], [b, c]] for the larger eigenvalue, without cancellation
    h = 0.5 * (a - c)
    r = math.hypot(h, b)
    if h >= 0.0:
        vx = h + r
        vy = b
    else:
        vx = b
        vy = r - h
    norm = math.hypot(vx, vy)
    if norm == 0.0:  # isotropic: any direction; LAPACK's choice
        return cx, cy, 0.0, 1.0
    return cx, cy, vx / norm, vy / norm


@njit(cache=True)
def _project(x: float, y: float, px: float, py: float, ux: float, uy: float) -> tuple[float, float]:
    t = (x - px) * ux + (y - py) * uy
    return px + t * ux, py + t * uy


@njit(cache=True)
def _fit(
    pts: np.ndarray,
    lo: int,
    hi: int,
    first_true: bool,
    last_true: bool,
    expected_width: float,
    hint_c: float,
    hint_s: float,
    min_points: int,
    corner_abs: float,
    corner_rel: float,
    max_width_factor: float,
    ray_step: float,
    out: np.ndarray,
    n: int,
) -> int:
    """Rear candidates of the cluster in rows lo:hi (see ``perception.fit_rear``)."""
    k = hi - lo
    if k < min_points:
        return n
    ax = pts[lo, 0]
    ay = pts[lo, 1]
    bx = pts[hi - 1, 0]
    by = pts[hi - 1, 1]
    chx = bx - ax
    chy = by - ay
    chord_len = math.hypot(chx, chy)
    # An L-shape (two options: either side as the rear) or a line (one).
    n_options = 1
    is_l = False
    swap = False
    kx = ky = rax = ray = lbx = lby = 0.0
    if chord_len > 0 and k >= 5:
        j = 0
        best = -1.0
        for q in range(k):
            off = abs(chx * (pts[lo + q, 1] - ay) - chy * (pts[lo + q, 0] - ax)) / chord_len
            if off > best:
                best = off
                j = q
        min_side = 2.0 * corner_abs
        jx = pts[lo + j, 0]
        jy = pts[lo + j, 1]
        if (
            best > max(corner_abs, corner_rel * chord_len)
            and 2 <= j <= k - 3
            and math.hypot(jx - ax, jy - ay) >= min_side
            and math.hypot(bx - jx, by - jy) >= min_side
        ):
            p1x, p1y, u1x, u1y = _tls_line(pts, lo, lo + j + 1)
            p2x, p2y, u2x, u2y = _tls_line(pts, lo + j, hi)
            den = u1x * u2y - u1y * u2x
            if abs(den) >= 1e-6 and abs(u1x * u2x + u1y * u2y) < MAX_CORNER_COS:
                wx = p2x - p1x
                wy = p2y - p1y
                t = (wx * u2y - wy * u2x) / den
                kx = p1x + t * u1x  # the corner
                ky = p1y + t * u1y
                rax, ray = _project(ax, ay, p1x, p1y, u1x, u1y)
                lbx, lby = _project(bx, by, p2x, p2y, u2x, u2y)
                swap = abs(u1x * hint_c + u1y * hint_s) > abs(u2x * hint_c + u2y * hint_s)
                is_l = True
                n_options = 2
    if not is_l:
        px, py, ux, uy = _tls_line(pts, lo, hi)
        rax, ray = _project(ax, ay, px, py, ux, uy)
        lbx, lby = _project(bx, by, px, py, ux, uy)
    for option in range(n_options):
        if not is_l:  # the line
            ea_x, ea_y, eb_x, eb_y = rax, ray, lbx, lby
            a_true, b_true = first_true, last_true
        elif (option == 0) != swap:  # the right side as the rear
            ea_x, ea_y, eb_x, eb_y = rax, ray, kx, ky
            a_true, b_true = first_true, is_l
        else:  # the left side as the rear
            ea_x, ea_y, eb_x, eb_y = kx, ky, lbx, lby
            a_true, b_true = is_l, last_true
        # the rear face from its right end ea to its left end eb (see fit_rear)
        spx = eb_x - ea_x
        spy = eb_y - ea_y
        width = math.hypot(spx, spy)
        if width > 1e-9:
            ux = spx / width
            uy = spy / width
        else:
            ux = -hint_s
            uy = hint_c
        if ray_step > 0.0:  # true ends: half a ray spacing out, on the face
            nx = uy
            ny = -ux
            if a_true:
                r = math.hypot(ea_x, ea_y)
                cos_inc = abs(ea_x * nx + ea_y * ny) / max(r, 1e-9)
                pad = 0.5 * r * ray_step / max(cos_inc, 0.3)
                ea_x = ea_x - pad * ux
                ea_y = ea_y - pad * uy
            if b_true:
                r = math.hypot(eb_x, eb_y)
                cos_inc = abs(eb_x * nx + eb_y * ny) / max(r, 1e-9)
                pad = 0.5 * r * ray_step / max(cos_inc, 0.3)
                eb_x = eb_x + pad * ux
                eb_y = eb_y + pad * uy
            width = math.hypot(eb_x - ea_x, eb_y - ea_y)
        if width > max_width_factor * expected_width:
            continue  # not a vehicle
        cx = 0.5 * (ea_x + eb_x)
        cy = 0.5 * (ea_y + eb_y)
        if width < expected_width:  # narrower than a rear: from its one true end
            half = 0.5 * expected_width
            if a_true and not b_true:
                cx = ea_x + half * ux
                cy = ea_y + half * uy
            elif b_true and not a_true:
                cx = eb_x - half * ux
                cy = eb_y - half * uy
        nx = uy  # right-hand normal of a right-to-left face, away from the sensor
        ny = -ux
        if nx * cx + ny * cy < 0:
            nx = -nx
            ny = -ny
        out[n, 0] = cx
        out[n, 1] = cy
        out[n, 2] = width
        out[n, 3] = math.atan2(ny, nx)
        out[n, 4] = 1.0 if (a_true and b_true) else 0.0
        out[n, 5] = 1.0 if is_l else 0.0
        out[n, 6] = 1.0 if option == 1 else 0.0
        out[n, 7] = lo
        out[n, 8] = hi
        n += 1
    return n


@njit(cache=True)
def fit_kernel(
    pts: np.ndarray,
    first_true: bool,
    last_true: bool,
    expected_width: float,
    hint_rad: float,
    min_points: int,
    corner_abs: float,
    corner_rel: float,
    max_width_factor: float,
    ray_step: float,
) -> np.ndarray:
    """Candidate rows (0, 1 or 2) of one cluster of points (k, 2), right to left."""
    out = np.empty((2, N_COLUMNS))
    lo = np.int64(0)  # not a literal 0: numba would compile _fit for it too
    n = _fit(
        pts, lo, pts.shape[0], first_true, last_true, expected_width, math.cos(hint_rad),
        math.sin(hint_rad), min_points, corner_abs, corner_rel, max_width_factor, ray_step,
        out, lo,
    )  # fmt: skip
    return out[:n]


@njit(cache=True)
def _end_is_true(ranges: np.ndarray, inside: int, outside: int) -> bool:
    if outside < 0 or outside >= ranges.size:
        return False  # cut by the field of view
    beyond = ranges[outside]
    if beyond != beyond:  # NaN
        return False  # unknown
    return beyond > ranges[inside]  # +inf (nothing) or farther: a true edge


PARAM_NAMES = (
    "break_abs_m",
    "break_angle_rad",
    "max_dropout_gap",
    "min_points",
    "corner_abs_m",
    "corner_rel",
    "max_width_factor",
)
"""The entries of ``detect``'s parameter array (``PerceptionParams``, the break angle in
radians, the two counts as floats)."""


@njit(cache=True)
def detect_into(
    ranges: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    angle_inc: float,
    params: np.ndarray,
    expected_width: float,
    hint_rad: float,
    use_roi: bool,
    roi_x: float,
    roi_y: float,
    roi_r: float,
    range_min: float,
    box_x: float,
    box_half: float,
    pts: np.ndarray,
    rows: np.ndarray,
) -> tuple[int, int, bool]:
    """Segment a scan and fit the rears of its clusters (those with a point within the
    region of interest, with ``use_roi``), into caller-owned buffers of as many rows as
    rays: the hit points (sensor frame) into ``pts``, the candidate rows into ``rows``.
    Returns (the number of points, of rows, whether anything is in the box ahead, see
    ``_segment``). ``cos_a`` / ``sin_a``: cosine and sine of each ray's angle;
    ``params``: the values of ``PARAM_NAMES``."""
    break_abs = params[0]
    lam = params[1]
    max_dropout_gap = int(params[2])
    min_points = int(params[3])
    corner_abs = params[4]
    corner_rel = params[5]
    max_width_factor = params[6]
    m, idx, starts, stops, boxed = _segment(
        ranges, cos_a, sin_a, angle_inc, break_abs, lam, max_dropout_gap, range_min, box_x,
        box_half, pts,
    )  # fmt: skip
    nc = starts.size
    n = np.int64(0)  # not a literal 0: numba would compile _fit for it too
    hint_c = math.cos(hint_rad)
    hint_s = math.sin(hint_rad)
    ray_step = abs(angle_inc)
    r2 = roi_r * roi_r
    for c in range(nc):
        lo = starts[c]
        hi = stops[c]
        if hi - lo < min_points:
            continue
        if use_roi:
            d2min = np.inf
            for q in range(lo, hi):
                dx = pts[q, 0] - roi_x
                dy = pts[q, 1] - roi_y
                d2min = min(d2min, dx * dx + dy * dy)
            if not d2min <= r2:
                continue
        i_first = idx[lo]
        i_last = idx[hi - 1]
        n = _fit(
            pts, lo, hi, _end_is_true(ranges, i_first, i_first - 1),
            _end_is_true(ranges, i_last, i_last + 1), expected_width, hint_c, hint_s,
            min_points, corner_abs, corner_rel, max_width_factor, ray_step, rows, n,
        )  # fmt: skip
    return m, n, boxed


@njit(cache=True)
def detect(
    ranges: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    angle_inc: float,
    params: np.ndarray,
    expected_width: float,
    hint_rad: float,
    use_roi: bool,
    roi_x: float,
    roi_y: float,
    roi_r: float,
) -> tuple[np.ndarray, np.ndarray]:
    """``detect_into`` with new arrays: (hit points (H, 2), candidate rows)."""
    pts = np.empty((ranges.size, 2))
    rows = np.empty((ranges.size, N_COLUMNS))
    m, n, _ = detect_into(
        ranges, cos_a, sin_a, angle_inc, params, expected_width, hint_rad, use_roi, roi_x,
        roi_y, roi_r, 0.0, -1.0, -1.0, pts, rows,
    )  # fmt: skip
    return pts[:m], rows[:n]


# ----------------------------------------------------------------------------- tracking

STATE_SIZE = 15
"""A track's state array: time, x, y, vx, vy and the upper triangle of the 4x4
covariance row by row (p00 p01 p02 p03 p11 p12 p13 p22 p23 p33)."""


@njit(cache=True)
def kalman_step(
    state: np.ndarray,
    time_s: float,
    rows: np.ndarray,
    pose_x: float,
    pose_y: float,
    pose_c: float,
    pose_s: float,
    accel_noise: float,
    meas_noise: float,
    gate_chi2: float,
    gate_floor: float,
) -> tuple[int, float, float, float, float, float, float]:
    """One scan of a constant-velocity track (``state``, updated in place): predict it to
    ``time_s``, associate the candidate row (sensor frame; the sensor at ``pose_x``,
    ``pose_y`` with heading cosine / sine ``pose_c``, ``pose_s``) with the smallest
    Mahalanobis distance inside the gate (chi-square ``gate_chi2``, or within
    ``gate_floor`` metres), and update with it. A row's measurement std is ``meas_noise``,
    doubled when it is not complete. Returns (the row, -1 for none; x, y, vx, vy; the
    position and velocity variances p00 + p11, p22 + p33)."""
    # (in place, without tuples of ten: numba compiles this three times faster)
    dt = max(time_s - state[0], 0.0)
    state[0] = time_s
    if dt != 0.0:  # predict: x = F x, P = F P F' + Q (F: constant velocity over dt)
        q = accel_noise * accel_noise
        g00 = dt**4 / 4 * q
        g01 = dt**3 / 2 * q
        g11 = dt**2 * q
        state[1] = state[1] + dt * state[3]
        state[2] = state[2] + dt * state[4]
        a02 = state[7] + dt * state[12]  # rows of F P
        a03 = state[8] + dt * state[13]
        a13 = state[11] + dt * state[14]
        state[5] = (state[5] + dt * state[7]) + dt * a02 + g00
        state[6] = (state[6] + dt * state[10]) + dt * a03
        state[7] = a02 + g01
        state[8] = a03
        state[9] = (state[9] + dt * state[11]) + dt * a13 + g00
        state[10] = state[10] + dt * state[13]
        state[11] = a13 + g01
        state[12] = state[12] + g11
        state[14] = state[14] + g11
    best = -1
    best_d2 = np.inf
    best_zx = 0.0
    best_zy = 0.0
    best_r = 0.0
    for k in range(rows.shape[0]):
        cx = rows[k, 0]
        cy = rows[k, 1]
        zx = pose_x + pose_c * cx - pose_s * cy
        zy = pose_y + pose_s * cx + pose_c * cy
        nu0 = zx - state[1]
        nu1 = zy - state[2]
        sigma = meas_noise * (1.0 if rows[k, 4] != 0.0 else 2.0)
        r = sigma * sigma
        s00 = state[5] + r
        s01 = state[6]
        s11 = state[9] + r
        d2 = (nu0 * (s11 * nu0 - s01 * nu1) + nu1 * (s00 * nu1 - s01 * nu0)) / (
            s00 * s11 - s01 * s01
        )
        inside = d2 <= gate_chi2 or math.hypot(nu0, nu1) <= gate_floor
        if inside and d2 < best_d2:
            best = k
            best_d2 = d2
            best_zx = zx
            best_zy = zy
            best_r = r
    if best >= 0:  # update with the position measured: K = P[:, :2] S^-1
        p = state[5:]  # p00 p01 p02 p03 p11 p12 p13 p22 p23 p33
        s00 = p[0] + best_r
        s01 = p[1]
        s11 = p[4] + best_r
        det = s00 * s11 - s01 * s01
        i00 = s11 / det
        i01 = -s01 / det
        i11 = s00 / det
        k00 = p[0] * i00 + p[1] * i01
        k01 = p[0] * i01 + p[1] * i11
        k10 = p[1] * i00 + p[4] * i01
        k11 = p[1] * i01 + p[4] * i11
        k20 = p[2] * i00 + p[5] * i01
        k21 = p[2] * i01 + p[5] * i11
        k30 = p[3] * i00 + p[6] * i01
        k31 = p[3] * i01 + p[6] * i11
        nu0 = best_zx - state[1]
        nu1 = best_zy - state[2]
        state[1] = state[1] + (k00 * nu0 + k01 * nu1)
        state[2] = state[2] + (k10 * nu0 + k11 * nu1)
        state[3] = state[3] + (k20 * nu0 + k21 * nu1)
        state[4] = state[4] + (k30 * nu0 + k31 * nu1)
        # P - K P[:2, :], upper triangle; the rows of P[:2, :] first (p is a view)
        r0 = (p[0], p[1], p[2], p[3])
        r1 = (p[1], p[4], p[5], p[6])
        p[0] = r0[0] - (k00 * r0[0] + k01 * r1[0])
        p[1] = r0[1] - (k00 * r0[1] + k01 * r1[1])
        p[2] = r0[2] - (k00 * r0[2] + k01 * r1[2])
        p[3] = r0[3] - (k00 * r0[3] + k01 * r1[3])
        p[4] = r1[1] - (k10 * r0[1] + k11 * r1[1])
        p[5] = r1[2] - (k10 * r0[2] + k11 * r1[2])
        p[6] = r1[3] - (k10 * r0[3] + k11 * r1[3])
        p[7] = p[7] - (k20 * r0[2] + k21 * r1[2])
        p[8] = p[8] - (k20 * r0[3] + k21 * r1[3])
        p[9] = p[9] - (k30 * r0[3] + k31 * r1[3])
    return best, state[1], state[2], state[3], state[4], state[5] + state[9], state[12] + state[14]
