"""The laser follower's step on a new scan while it holds a track, in one kernel call.

``LaserFollower.step`` in Python makes about ten calls into compiled code for such a
step (the route projection, ``perceive_kernel``, the corridor tests, the fallback's
projection, ``follow_kernel``, the lane request), each with its own dispatch and the
glue between them: about 50 µs a step in the co-simulation, of which the arithmetic is
a fifth. ``following_step_kernel`` runs the same calls in the same order with the same
arguments (``platoon_sumo.control.laser_follower``'s methods are the specification; the
names in the comments are theirs) and hands back what the controller keeps between
steps. The Python path stays for every other case (no track, no new scan, no corridor,
a full trail buffer) and is the oracle of ``tests/control/test_laser_follower_fused.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literal_unroll, njit

from platoon_sumo.kernels.follower import follow_kernel, perceive_kernel
from platoon_sumo.kernels.route import (
    _pmax,
    _point_at,
    lane_step_kernel,
    project_pruned,
    same_lane_kernel,
)

FOLLOWED = 0
"""The whole step is done: the command's speed, yaw rate and lane request are given."""
LOST = 1
"""The scan was processed but the track is not confirmed (or was dropped): the caller
goes on with the lost branch."""
LANE_UNREAD = 2
"""Done but for the lane request, which the caller asks the path (lane ids the kernels
cannot read as numbers)."""
RAISE = 3
"""A projection's hint or window is not finite: the caller raises what
``RoutePath.project_lane`` raises for them (nothing is to be kept)."""

PARAM_NAMES = (
    "corridor_lane",
    "corridor_value",
    "corridor_exit_s",
    "confirm_scans",
    "max_missed_scans",
    "lost_after_s",
    "trail_spacing_m",
    "max_trail_points",
    "steer_at_trail",
    "fallback_lookahead_min_m",
    "fallback_lookahead_time_s",
)
"""The entries of ``following_step_kernel``'s ``params``: the corridor (1: "lane", with
``corridor_value`` its margin in lane widths; 0: a half-width of ``corridor_value``
metres), the track's exit and loss rules, the trail's spacing and size, the steering
target (1: the trail) and the fallback's look-ahead."""


@njit(cache=True)
def _valid_window(hint: float, window: float) -> bool:
    """``RoutePath.project_lane``'s check of its hint and window."""
    return math.isfinite(hint) and window >= 0.0 and window < math.inf


@njit(cache=True)
def _raising(route_s: float, fallback_s: float, x: float, y: float, hint: float, window: float):
    """The kernel's result for ``RAISE``: the projection's point, hint and window (the
    rest is never read)."""
    return (RAISE, route_s, 0.0, 0.0, 0.0, False, -1, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
            False, False, False, 0, 0, 0.0, 0.0, fallback_s, 0.0, 0.0, 0.0, 0.0, 0.0,
            0.0, 0.0, 0.0, 0.0, 0, False, x, y, hint, window)  # fmt: skip


@njit(cache=True)
def _ahead_on_route(
    xy: np.ndarray,
    blocks: np.ndarray,
    widths: np.ndarray,
    spacing: float,
    path_length: float,
    route_s: float,
    x: float,
    y: float,
    length: float,
    px: float,
    py: float,
    lane_offset: float,
    lane_corridor: bool,
    corridor_value: float,
) -> tuple[bool, float, float, float, float, bool, bool]:
    """``LaserFollower._ahead_on_route`` and ``_in_corridor`` for the point (px, py), the
    follower at (x, y) and ``route_s`` on its route: (the projection's hint and window
    are valid, hint, window, the point's arc length and lateral offset, whether it is
    ahead, whether it is inside the corridor)."""
    reach = 0.5 * (math.hypot(px - x, py - y) + 3.0 * length)
    hint = route_s + reach
    if not _valid_window(hint, reach):
        return False, hint, reach, 0.0, 0.0, False, False
    at_s, at_lateral, at_width = project_pruned(
        xy, blocks, widths, spacing, path_length, True, hint, reach, px, py
    )
    ahead = not at_s <= route_s  # a NaN arc length counts as ahead, as in Python
    inside = False
    if ahead:
        half_width = (0.5 + corridor_value) * at_width if lane_corridor else corridor_value
        inside = abs(at_lateral - lane_offset) <= half_width
    return True, hint, reach, at_s, at_lateral, ahead, inside


@njit(cache=True)
def following_step_kernel(
    xy: np.ndarray,
    blocks: np.ndarray,
    widths: np.ndarray,
    codes: np.ndarray,
    spans: np.ndarray,
    shift: np.ndarray,
    geometry: np.ndarray,
    ranges: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    consts: np.ndarray,
    perception: np.ndarray,
    state: np.ndarray,
    pts: np.ndarray,
    rows: np.ndarray,
    cand_pts: np.ndarray,
    cand_row: np.ndarray,
    trail: np.ndarray,
    law: np.ndarray,
    params: np.ndarray,
    time_s: float,
    dt: float,
    x: float,
    y: float,
    yaw: float,
    speed: float,
    front: float,
    length: float,
    lane_offset: float,
    look: float,
    route_s: float,
    fallback_s: float,
    ox: float,
    oy: float,
    heading: float,
    hits: int,
    missed: int,
    last_hit_s: float,
    lo: int,
    hi: int,
    last_x: float,
    last_y: float,
    has_since: bool,
    since: float,
):
    """One step of a laser follower with an active track and a new scan (see the module
    docstring): ``_locate_on_route``, ``_perceive`` (the track's update, the corridor
    test and exit rule, the trail), and while the track is confirmed the fallback's
    ``advance`` and ``_follow``. The trail is rows ``lo:hi`` of ``trail``, which has room
    for one more; ``state`` is the tracker's filter state (updated in place).

    Returns (status, arc length on the route, mount x, y, yaw, blocked, the row
    associated, its cluster's points, the track's x, y, vx, vy, position and velocity
    variances, dropped at the corridor's exit, outside the corridor (the caller keeps
    since when), in view, trail lo, hi, last point x, y, the fallback's arc length, speed, yaw
    rate, gap, range rate, lead speed, the rear's range and bearing, predicted rear x,
    y, lane request, keep the lane, and for ``RAISE`` the projection's x, y, hint and
    window)."""
    spacing = geometry[0]
    path_length = geometry[1]
    last_step = geometry[2]
    lane_corridor = params[0] != 0.0
    corridor_value = params[1]
    nan = math.nan
    # _locate_on_route
    window = _pmax(4.0 * length, 2.0 * look)
    if not _valid_window(route_s, window):
        return _raising(route_s, fallback_s, x, y, route_s, window)
    route_s, _, _ = project_pruned(
        xy, blocks, widths, spacing, path_length, True, route_s, window, x, y
    )
    # _perceive: the sensor pose, then perceive_kernel with the active track
    c = math.cos(yaw)
    s = math.sin(yaw)
    dx = ox - x
    dy = oy - y
    mount_x = c * dx + s * dy
    mount_y = -s * dx + c * dy
    mount_yaw = heading - yaw
    _, _, blocked, k, n_cand, tx, ty, tvx, tvy, var_p, var_v = perceive_kernel(
        ranges, cos_a, sin_a, consts, perception, True, state, time_s, ox, oy, heading, pts,
        rows, cand_pts, cand_row,
    )  # fmt: skip
    # RearTracker.record_step
    active = True
    if k < 0:
        missed += 1
        if not hits >= params[3] or missed > params[4] or time_s - last_hit_s > params[5]:
            active = False
            hits = 0
        k = -1
    else:
        hits += 1
        missed = 0
    hit = k >= 0
    # the corridor test of the track's position (_in_corridor / _ahead_on_route)
    inside = False
    if active:
        valid, hint, reach, _, _, _, inside = _ahead_on_route(
            xy, blocks, widths, spacing, path_length, route_s, x, y, length, tx, ty,
            lane_offset, lane_corridor, corridor_value,
        )  # fmt: skip
        if not valid:
            return _raising(route_s, fallback_s, tx, ty, hint, reach)
    dropped = False
    if not active or inside:
        has_since = False
    elif not has_since:
        has_since = True
        since = time_s
    elif time_s - since > params[2]:
        dropped = True  # it turned off the route: lost
        active = False
        hits = 0
        has_since = False
        hit = False
    # _append_trail
    if hit and inside and (hi == lo or math.hypot(tx - last_x, ty - last_y) >= params[6]):
        trail[hi, 0] = tx
        trail[hi, 1] = ty
        hi += 1
        if hi - lo > params[7]:
            lo += 1
        last_x = tx
        last_y = ty
    if not (active and hits >= params[3]):
        return (LOST, route_s, mount_x, mount_y, mount_yaw, blocked, k, n_cand, tx, ty, tvx,
                tvy, var_p, var_v, dropped, has_since, hit, lo, hi, last_x, last_y,
                fallback_s, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, False, nan, nan,
                nan, nan)  # fmt: skip
    # _RouteShadow.advance
    fallback_look = _pmax(params[9], params[10] * speed)
    fallback_window = _pmax(20.0, 3 * fallback_look)
    if not _valid_window(fallback_s, fallback_window):
        return _raising(route_s, fallback_s, x, y, fallback_s, fallback_window)
    fallback_s, _, _ = project_pruned(
        xy, blocks, widths, spacing, path_length, True, fallback_s, fallback_window, x, y
    )
    # _follow: the track predicted to now (RearTracker.predicted_state, at its own time)
    gone = _pmax(time_s - time_s, 0.0)
    rx = tx + gone * tvx
    ry = ty + gone * tvy
    valid, hint, reach, at_s, at_lateral, ahead, rear_inside = _ahead_on_route(
        xy, blocks, widths, spacing, path_length, route_s, x, y, length, rx, ry, lane_offset,
        lane_corridor, corridor_value,
    )  # fmt: skip
    if not valid:
        return _raising(route_s, fallback_s, rx, ry, hint, reach)
    route_x = 0.0
    route_y = 0.0
    if not rear_inside:
        route_x, route_y = _point_at(xy, spacing, path_length, last_step, route_s + look)
    lo, cmd, yaw_rate, gap, range_rate, lead_speed, range_m, bearing = follow_kernel(
        trail, lo, hi, law, params[8] != 0.0, x, y, yaw, speed, front, dt, look, rx, ry, tvx,
        tvy, rear_inside, not rear_inside, route_x, route_y, mount_x, mount_y, mount_yaw,
    )  # fmt: skip
    # _lane_request
    status = FOLLOWED
    lane = 0
    keep = False
    if hit and ahead:
        if codes.shape[0] == 0:
            status = LANE_UNREAD
        else:
            lane = lane_step_kernel(
                codes, widths, spans, spacing, route_s, lane_offset, at_s, at_lateral
            )
            if lane == -2:
                status = LANE_UNREAD
                lane = 0
            elif lane == 0:
                same = same_lane_kernel(
                    codes, widths, shift, spacing, route_s, lane_offset, at_s, at_lateral
                )
                if same == -2:
                    status = LANE_UNREAD
                keep = same == 1
    return (status, route_s, mount_x, mount_y, mount_yaw, blocked, k, n_cand, tx, ty, tvx, tvy,
            var_p, var_v, dropped, has_since, hit, lo, hi, last_x, last_y, fallback_s,
            cmd, yaw_rate, gap, range_rate, lead_speed, range_m, bearing, rx, ry, lane, keep,
            nan, nan, nan, nan)  # fmt: skip


OUTPUT_SIZE = 37
"""The number of values ``following_step_kernel`` returns (a row of
``following_batch_kernel``'s output)."""

SKIPPED = 4
"""``following_batch_kernel``: the step did not run (no room left in the trail); the
caller steps the follower itself."""

STATE_NAMES = (
    "route_s", "fallback_s", "hits", "missed", "last_hit_s", "trail_lo", "trail_hi",
    "trail_last_x", "trail_last_y", "has_since", "since", "hit_since_joined", "track_time_s",
    "track_x", "track_y", "track_vx", "track_vy", "track_var_p", "track_var_v", "mount_x",
    "mount_y", "mount_yaw", "cand_n", "has_track", "track_range_m", "track_bearing_rad",
    "track_range_rate_mps", "track_in_view", "track_speed_mps", "track_rear_x",
    "track_rear_y",
)  # fmt: skip
"""A follower's numbers between steps in ``following_batch_kernel``'s ``state_rows``
(the controller's attributes of those names while it is stepped there)."""
(
    S_ROUTE, S_FALLBACK, S_HITS, S_MISSED, S_LAST_HIT, S_LO, S_HI, S_LAST_X, S_LAST_Y,
    S_HAS_SINCE, S_SINCE, S_HIT_SINCE_JOINED, S_TRACK_TIME, S_TX, S_TY, S_TVX, S_TVY,
    S_VAR_P, S_VAR_V, S_MOUNT_X, S_MOUNT_Y, S_MOUNT_YAW, S_CAND_N, S_HAS_TRACK, S_RANGE,
    S_BEARING, S_RANGE_RATE, S_IN_VIEW, S_LEAD_SPEED, S_RX, S_RY,
) = range(len(STATE_NAMES))  # fmt: skip
INPUT_NAMES = (
    "time_s", "dt_s", "x_m", "y_m", "yaw_rad", "speed_mps", "front_offset_m", "length_m",
    "lane_offset_m", "look_m", "scan_x_m", "scan_y_m", "scan_heading_rad",
)  # fmt: skip
"""A follower's inputs of one step in ``following_batch_kernel``'s ``inputs``."""


@njit(cache=True)
def following_batch_kernel(
    xy: np.ndarray,
    xy_starts: np.ndarray,
    blocks: np.ndarray,
    block_starts: np.ndarray,
    widths: np.ndarray,
    width_starts: np.ndarray,
    codes: np.ndarray,
    code_starts: np.ndarray,
    spans: np.ndarray,
    span_starts: np.ndarray,
    shift: np.ndarray,
    shift_starts: np.ndarray,
    geometry: np.ndarray,
    path_of: np.ndarray,
    ranges: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    consts: np.ndarray,
    perception: np.ndarray,
    state: np.ndarray,
    pts: np.ndarray,
    rows: np.ndarray,
    cand_pts: np.ndarray,
    cand_row: np.ndarray,
    trail: np.ndarray,
    law: np.ndarray,
    params: np.ndarray,
    state_rows: np.ndarray,
    slot_of: np.ndarray,
    inputs: np.ndarray,
) -> np.ndarray:
    """``following_step_kernel`` for many followers in one call. Follower j is on path
    ``p = path_of[j]``: its points are rows ``xy_starts[p]:xy_starts[p + 1]`` of ``xy``,
    its blocks, lane widths, lane codes, lane-change spans and lane shifts the rows of
    ``blocks``, ``widths``, ``codes``, ``spans`` and ``shift`` between their starts, its
    geometry row p of ``geometry``. It scans ``ranges[j]``, reads ``inputs[j]``
    (``INPUT_NAMES``) and keeps what it keeps between steps in row ``slot_of[j]`` of
    the pooled arrays (rays' cosines and sines, constants, perception parameters, track
    filter, candidate, trail, spacing law and parameters) and of ``state_rows``
    (``STATE_NAMES``); ``pts`` and ``rows`` are the shared scratch buffers.

    Row j of the result holds the values of its ``following_step_kernel`` call, in
    order, as numbers (status ``SKIPPED`` without a call: its trail is full). Only a
    ``FOLLOWED`` step is booked in ``state_rows`` (as ``LaserFollower`` books it); for
    any other status the row is left as it was, the arrays as the kernel left them, and
    the caller books the values as after a single call."""
    n = path_of.shape[0]
    out = np.empty((n, OUTPUT_SIZE))
    for j in range(n):
        p = path_of[j]
        q = slot_of[j]
        v = inputs[j]
        s = state_rows[q]
        lo = int(s[S_LO])
        hi = int(s[S_HI])
        if hi >= trail.shape[1]:
            out[j, :] = math.nan
            out[j, 0] = SKIPPED
            continue
        time_s = v[0]
        res = following_step_kernel(
            xy[xy_starts[p] : xy_starts[p + 1]], blocks[block_starts[p] : block_starts[p + 1]],
            widths[width_starts[p] : width_starts[p + 1]],
            codes[code_starts[p] : code_starts[p + 1]], spans[span_starts[p] : span_starts[p + 1]],
            shift[shift_starts[p] : shift_starts[p + 1]], geometry[p], ranges[j], cos_a[q],
            sin_a[q], consts[q], perception[q], state[q], pts, rows, cand_pts[q], cand_row[q],
            trail[q], law[q], params[q], time_s, v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8],
            v[9], s[S_ROUTE], s[S_FALLBACK], v[10], v[11], v[12], int(s[S_HITS]),
            int(s[S_MISSED]), s[S_LAST_HIT], lo, hi, s[S_LAST_X], s[S_LAST_Y],
            s[S_HAS_SINCE] != 0.0, s[S_SINCE],
        )  # fmt: skip
        row = out[j]
        i = 0
        for value in literal_unroll(res):  # its values, mixed types, as numbers
            row[i] = value
            i += 1  # noqa: SIM113 (numba unrolls no enumerate of literal_unroll)
        if res[0] != FOLLOWED:
            continue
        # booked as LaserFollower._fused_apply and RearTracker.record_step book it
        s[S_ROUTE] = res[1]
        s[S_MOUNT_X] = res[2]
        s[S_MOUNT_Y] = res[3]
        s[S_MOUNT_YAW] = res[4]
        k = res[6]
        s[S_CAND_N] = res[7]
        s[S_TRACK_TIME] = time_s
        s[S_TX] = res[8]
        s[S_TY] = res[9]
        s[S_TVX] = res[10]
        s[S_TVY] = res[11]
        s[S_VAR_P] = res[12]
        s[S_VAR_V] = res[13]
        if k < 0:
            s[S_MISSED] += 1.0
        else:
            s[S_HITS] += 1.0
            s[S_MISSED] = 0.0
            s[S_LAST_HIT] = time_s
            s[S_HIT_SINCE_JOINED] = 1.0
        if res[15]:
            if s[S_HAS_SINCE] == 0.0:
                s[S_SINCE] = time_s
            s[S_HAS_SINCE] = 1.0
        else:
            s[S_HAS_SINCE] = 0.0
            s[S_SINCE] = 0.0
        s[S_LO] = res[17]
        s[S_HI] = res[18]
        s[S_LAST_X] = res[19]
        s[S_LAST_Y] = res[20]
        s[S_FALLBACK] = res[21]
        s[S_HAS_TRACK] = 1.0
        s[S_RANGE] = res[27]
        s[S_BEARING] = res[28]
        s[S_RANGE_RATE] = res[25]
        s[S_IN_VIEW] = res[16]
        s[S_LEAD_SPEED] = res[26]
        s[S_RX] = res[29]
        s[S_RY] = res[30]
    return out
