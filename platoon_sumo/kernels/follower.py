"""Laser-follower kernels: one call per new scan (rear detection, the blocked check and
the track update),
the arc clearance over a scan's rays, and the trail geometry (pruning, length, pursuit
target) over a trail held in rows ``lo:hi`` of an (n, 2) buffer. The arithmetic is that
of ``platoon_sumo.control.laser_follower``'s docstrings and methods, ray by ray and point
by point.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from platoon_sumo.kernels.perception import detect_into, kalman_step

CONST_NAMES = (
    "angle_increment",
    "range_min",
    "width_m",
    "min_gap_m",
    "accel_noise_mps2",
    "meas_noise_m",
    "gate_chi2",
)
"""The entries of ``perceive_kernel``'s constants: the scan's ray spacing and minimum
range, the predecessor's expected rear width, the blocked distance and the tracker's
noises and gate."""


@njit(cache=True)
def perceive_kernel(
    ranges: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    consts: np.ndarray,
    params: np.ndarray,
    active: bool,
    state: np.ndarray,
    time_s: float,
    pose_x: float,
    pose_y: float,
    pose_heading: float,
    pts: np.ndarray,
    rows: np.ndarray,
    cand_pts: np.ndarray,
    cand_row: np.ndarray,
) -> tuple[int, int, bool, int, int, float, float, float, float, float, float]:
    """All of a new scan's work in one call, for a sensor at the pose (world frame), with
    cosine / sine tables of its rays, ``consts`` (``CONST_NAMES``) and the detection's
    ``params``:

    1. with an ``active`` track (``state``, see ``perception.kalman_step``): a region of
       interest around the predicted rear (the gate's spread, at least half a width, plus
       a width) and a heading hint (the track's velocity direction when its speed is
       significant, more than twice its std);
    2. ``perception.detect_into`` in it: hit points into ``pts``, candidate rows into
       ``rows`` (buffers of as many rows as rays);
    3. blocked: anything within ``min_gap_m`` ahead of the sensor and half a width to the
       sides, or a ``-inf`` reading (closer than ``range_min``: position unknown, assume
       the worst) whose ray could be there;
    4. with an active track, ``kalman_step`` on the rows (the gate's floor: half a width);
       the row associated is copied to ``cand_row``, its cluster's points to the first
       rows of ``cand_pts``.

    Returns (points, rows, blocked, the row associated or -1, its cluster's points, and
    the track's x, y, vx, vy, position and velocity variances).
    """
    angle_inc = consts[0]
    range_min = consts[1]
    width = consts[2]
    min_gap = consts[3]
    gate_chi2 = consts[6]
    c = math.cos(pose_heading)
    s = math.sin(pose_heading)
    roi_x = 0.0
    roi_y = 0.0
    roi_r = 0.0
    hint = 0.0
    if active:
        dt = max(time_s - state[0], 0.0)
        dx = (state[1] + dt * state[3]) - pose_x
        dy = (state[2] + dt * state[4]) - pose_y
        roi_x = c * dx + s * dy
        roi_y = -s * dx + c * dy
        spread = math.sqrt(gate_chi2 * ((state[5] + state[9]) + 0.04))
        roi_r = max(spread, 0.5 * width) + width
        vx = state[3]
        vy = state[4]
        sigma = math.sqrt(max(state[12] + state[14], 0.0))
        heading = math.atan2(vy, vx) if math.hypot(vx, vy) > 2.0 * sigma else pose_heading
        hint = heading - pose_heading
    m, n, is_blocked = detect_into(
        ranges, cos_a, sin_a, angle_inc, params, width, hint, active, roi_x, roi_y, roi_r,
        range_min, min_gap, 0.5 * width, pts, rows,
    )  # fmt: skip
    if not active:
        return m, n, is_blocked, -1, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    k, x, y, vx, vy, var_p, var_v = kalman_step(
        state, time_s, rows[:n], pose_x, pose_y, c, s, consts[4], consts[5], gate_chi2,
        0.5 * width,
    )  # fmt: skip
    n_cand = 0
    if k >= 0:
        lo = int(rows[k, 7])
        n_cand = int(rows[k, 8]) - lo
        for q in range(n_cand):
            cand_pts[q, 0] = pts[lo + q, 0]
            cand_pts[q, 1] = pts[lo + q, 1]
        for j in range(rows.shape[1]):
            cand_row[j] = rows[k, j]
    return m, n, is_blocked, k, n_cand, x, y, vx, vy, var_p, var_v


@njit(cache=True)
def arc_clearance_kernel(
    ranges: np.ndarray,
    angle_min: float,
    angle_inc: float,
    origin_x: float,
    origin_y: float,
    heading: float,
    bumper_x: float,
    bumper_y: float,
    c: float,
    s: float,
    half_width: float,
    curvature: float,
) -> float:
    """Free distance from the bumper (heading (c, s)) along the arc of ``curvature``: the
    nearest hit point (world frame, from the scan's pose) within ``half_width`` of it."""
    best = np.inf
    straight = abs(curvature) < 1e-4
    radius = 1.0 if straight else 1.0 / abs(curvature)
    for i in range(ranges.size):
        r = ranges[i]
        if not abs(r) < np.inf:  # not finite
            continue
        a = heading + (angle_min + i * angle_inc)
        dx = (origin_x + r * np.cos(a)) - bumper_x
        dy = (origin_y + r * np.sin(a)) - bumper_y
        x = c * dx + s * dy
        y = -s * dx + c * dy
        if straight:
            along = x
            lateral = abs(y)
        else:
            if curvature <= 0:
                y = -y  # mirror right turns into left turns
            along = radius * math.atan2(x, radius - y)
            lateral = abs(math.hypot(x, y - radius) - radius)
        if along > 0.0 and lateral <= half_width and along < best:
            best = along
    return best


@njit(cache=True)
def start_gate_kernel(rows: np.ndarray, range_max: float, lateral_max: float) -> np.ndarray:
    """The candidate rows (``CANDIDATE_COLUMNS``) a new track may start on: ahead of the
    sensor within ``range_max``, within ``lateral_max`` of its axis, not an alternative
    fit (``RearTracker._start``'s gate), in row order."""
    keep = np.empty(rows.shape[0], np.int64)
    n = 0
    for j in range(rows.shape[0]):
        x = rows[j, 0]
        if 0.0 < x <= range_max and abs(rows[j, 1]) <= lateral_max and rows[j, 6] == 0.0:
            keep[n] = j
            n += 1
    return keep[:n]


@njit(cache=True)
def _trail(
    buf: np.ndarray,
    lo: int,
    hi: int,
    x: float,
    y: float,
    c: float,
    s: float,
    want_length: bool,
    bx: float,
    by: float,
    want_target: bool,
    has_end: bool,
    end_x: float,
    end_y: float,
    look: float,
) -> tuple[int, float, int, float, float]:
    """The trail's work of one step. The trail is rows ``lo:hi`` of ``buf``; (x, y) is the
    reference point and (c, s) the heading.

    1. Prune: the leading points behind the reference point are dropped, keeping one for
       interpolation; the new ``lo`` is returned.
    2. With ``want_length``: the length from the bumper (bx, by) along the pruned trail,
       from its first point ahead of the bumper, extended to ``end`` (else 0).
    3. With ``want_target``: the pursuit target, the point of the trail (extended to
       ``end`` with ``has_end``) one look-ahead from the reference point and ahead of it,
       on the segment that crosses the look-ahead circle: (1, point); (0, last point)
       when no point is that far; (-1, 0, 0) without points.

    Returns (lo, length, found, target x, target y).
    """
    if hi - lo >= 2:
        first = hi
        for i in range(lo, hi):
            if (buf[i, 0] - x) * c + (buf[i, 1] - y) * s > 0.0:
                first = i
                break
        if first - 1 > lo:
            lo = first - 1
    length = 0.0
    if want_length:
        first = hi
        for i in range(lo, hi):
            if (buf[i, 0] - bx) * c + (buf[i, 1] - by) * s > 0.0:
                first = i
                break
        if first == hi:
            length = math.hypot(end_x - bx, end_y - by)
        else:
            total = 0.0
            for i in range(first + 1, hi):
                total += math.hypot(buf[i, 0] - buf[i - 1, 0], buf[i, 1] - buf[i - 1, 1])
            total += math.hypot(end_x - buf[hi - 1, 0], end_y - buf[hi - 1, 1])
            length = math.hypot(buf[first, 0] - bx, buf[first, 1] - by) + total
    if not want_target:
        return lo, length, -1, 0.0, 0.0
    n = hi - lo + (1 if has_end else 0)
    if n == 0:
        return lo, length, -1, 0.0, 0.0
    prev_d = 0.0
    prev_x = 0.0
    prev_y = 0.0
    for j in range(n):
        if lo + j < hi:
            px = buf[lo + j, 0]
            py = buf[lo + j, 1]
        else:
            px = end_x
            py = end_y
        d = math.hypot(px - x, py - y)
        if d >= look and (px - x) * c + (py - y) * s > 0.0:
            if j == 0 or prev_d >= look:
                return lo, length, 1, px, py
            # the point of segment (j-1, j) at distance `look` from (x, y)
            ex = px - prev_x
            ey = py - prev_y
            wx = prev_x - x
            wy = prev_y - y
            qa = ex * ex + ey * ey
            qb = 2.0 * (wx * ex + wy * ey)
            qc = (wx * wx + wy * wy) - look * look
            disc = max(qb * qb - 4.0 * qa * qc, 0.0)
            t = (-qb + math.sqrt(disc)) / (2.0 * qa) if qa > 0 else 1.0
            t = min(max(t, 0.0), 1.0)
            return lo, length, 1, prev_x + t * ex, prev_y + t * ey
        prev_d = d
        prev_x = px
        prev_y = py
    return lo, length, 0, prev_x, prev_y


@njit(cache=True)
def trail_kernel(
    buf: np.ndarray,
    lo: int,
    hi: int,
    x: float,
    y: float,
    c: float,
    s: float,
    want_length: bool,
    bx: float,
    by: float,
    want_target: bool,
    has_end: bool,
    end_x: float,
    end_y: float,
    look: float,
) -> tuple[int, float, int, float, float]:
    """``_trail`` (the trail's work of one step) called from Python."""
    return _trail(
        buf, lo, hi, x, y, c, s, want_length, bx, by, want_target, has_end, end_x, end_y, look
    )


@njit(cache=True)
def krauss_safe_speed(room: float, lead_speed: float, decel: float, tau: float) -> float:
    """Highest speed from which the vehicle can stop within ``room`` behind a lead braking
    at ``decel`` (Krauss-style, reaction time ``tau``)."""
    if room <= 0.0:
        return 0.0
    bt = decel * tau
    return -bt + math.sqrt(bt * bt + lead_speed**2 + 2.0 * decel * room)


@njit(cache=True)
def pursuit(
    speed_cmd: float,
    speed: float,
    max_decel: float,
    max_accel: float,
    dt: float,
    x: float,
    y: float,
    yaw: float,
    tx: float,
    ty: float,
) -> float:
    """Pure-pursuit yaw rate towards (tx, ty) at the speed the vehicle will reach this step
    (the command within what the limits allow from ``speed`` in ``dt``)."""
    next_speed = min(max(speed_cmd, speed - max_decel * dt), speed + max_accel * dt)
    dx = tx - x
    dy = ty - y
    dist = math.hypot(dx, dy)
    if dist < 1e-6:
        return 0.0
    alpha = math.atan2(dy, dx) - yaw
    return max(next_speed, 0.0) * 2.0 * math.sin(alpha) / dist


LAW_NAMES = (
    "k_gap_1ps2",
    "k_rate_1ps",
    "standstill_gap_m",
    "time_gap_s",
    "min_gap_m",
    "comfort_decel_mps2",
    "reaction_time_s",
    "max_decel_mps2",
    "max_accel_mps2",
    "max_speed_mps",
)
"""The entries of ``follow_kernel``'s parameter array: the follower's parameters
(``time_gap_s`` 0 for a constant distance) and the vehicle's limits."""


@njit(cache=True)
def follow_kernel(
    buf: np.ndarray,
    lo: int,
    hi: int,
    law: np.ndarray,
    on_trail: bool,
    x: float,
    y: float,
    yaw: float,
    speed: float,
    front: float,
    dt: float,
    look: float,
    rx: float,
    ry: float,
    vx: float,
    vy: float,
    rear_in_corridor: bool,
    has_route_target: bool,
    route_x: float,
    route_y: float,
    mount_x: float,
    mount_y: float,
    mount_yaw: float,
) -> tuple[int, float, float, float, float, float, float, float]:
    """One step of following the predecessor whose rear is predicted at (rx, ry) moving at
    (vx, vy), for a vehicle at (x, y, yaw) at ``speed`` with its bumper ``front`` ahead
    (see ``LaserFollower``'s docstring):

    - gap: straight line from the bumper to the rear; its rate along the line of sight;
    - the trail's work (``_trail``): pruning, with ``on_trail`` its length from the bumper
      to the rear (the spacing then runs along it, at the lead speed minus the own) and
      the pursuit target on it (the rear ends the trail only inside the route corridor;
      ``route`` target when no trail point is far enough);
    - the spacing law ``k_gap (gap - desired) + k_rate rate``, clipped to the limits,
      integrated over ``dt``, capped by the Krauss safe speed on the straight-line gap
      and the closing speed, and the speed limit (``law``: ``LAW_NAMES``);
    - pure pursuit of the target (without ``on_trail``: the rear itself inside the
      corridor, else the route target);
    - the rear as the sensor (mounted at ``mount_*`` on the vehicle) sees it now.

    Returns (trail lo, speed, yaw rate, gap, range rate, lead speed, the rear's range and
    bearing from the sensor).
    """
    k_gap = law[0]
    k_rate = law[1]
    standstill = law[2]
    time_gap = law[3]
    min_gap = law[4]
    comfort_decel = law[5]
    reaction_time = law[6]
    max_decel = law[7]
    max_accel = law[8]
    max_speed = law[9]
    c = math.cos(yaw)
    s = math.sin(yaw)
    fx = x + front * c
    fy = y + front * s
    gap = math.hypot(rx - fx, ry - fy)
    if gap > 1e-9:
        ux = (rx - fx) / gap
        uy = (ry - fy) / gap
    else:
        ux = c
        uy = s
    own_vx = speed * c
    own_vy = speed * s
    range_rate = ux * (vx - own_vx) + uy * (vy - own_vy)
    lead_speed = math.hypot(vx, vy)
    lo, trail_gap, found, tx, ty = _trail(
        buf, lo, hi, x, y, c, s, on_trail, fx, fy, on_trail, rear_in_corridor, rx, ry, look
    )
    # Spacing along the predecessor's path (the trail), not the chord: in a curve the
    # chord is shorter and its rate mixes in the turning, which would brake the follower.
    if on_trail:
        path_gap = max(trail_gap, gap)
        gap_rate = lead_speed - speed
    else:
        path_gap = gap
        gap_rate = range_rate
    error = path_gap - (standstill + time_gap * max(speed, 0.0))
    accel = k_gap * error + k_rate * gap_rate
    accel = min(max(accel, -max_decel), max_accel)
    # Safety on the straight-line gap and the closing speed along the line of sight.
    safe = krauss_safe_speed(
        gap - min_gap, max(ux * vx + uy * vy, 0.0), comfort_decel, reaction_time
    )
    cmd = min(max(speed + accel * dt, 0.0), safe, max_speed)
    has_target = True
    if on_trail:
        if found < 0 or (found == 0 and has_route_target and not rear_in_corridor):
            has_target = has_route_target and not rear_in_corridor
            tx = route_x
            ty = route_y
    elif rear_in_corridor:
        tx = rx
        ty = ry
    else:
        has_target = has_route_target
        tx = route_x
        ty = route_y
    yaw_rate = 0.0
    if has_target:
        yaw_rate = pursuit(cmd, speed, max_decel, max_accel, dt, x, y, yaw, tx, ty)
    # the rear as the sensor sees it now (its mount on the vehicle is fixed)
    dx = rx - (x + c * mount_x - s * mount_y)
    dy = ry - (y + s * mount_x + c * mount_y)
    sc = math.cos(yaw + mount_yaw)
    ss = math.sin(yaw + mount_yaw)
    sx = sc * dx + ss * dy
    sy = -ss * dx + sc * dy
    return lo, cmd, yaw_rate, gap, range_rate, lead_speed, math.hypot(sx, sy), math.atan2(sy, sx)
