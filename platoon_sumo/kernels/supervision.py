"""The speed bounds of the traffic rules, and the supervisor's check of all members at
once with them (``supervisor.supervise_many``).

The bounds are plain Python functions of numbers: the controllers call them as they are
(``control.rules``), and the supervisor's kernel compiles the same functions, so the two
cannot drift apart."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def stop_speed_limit(
    distance_m: float,
    yellow: bool,
    speed_mps: float,
    dt_s: float,
    comfort_decel_mps2: float,
    yellow_max_decel_mps2: float,
    stop_margin_m: float,
) -> float:
    """Highest speed that still stops `stop_margin_m` before a stop line `distance_m`
    ahead (red, or `yellow`). Plain numbers only: compiled as it is for the supervisor's
    batch (`supervise_kernel`); `control.rules` has it for the controllers.

    Braking starts when the comfortable deceleration is needed; a light that changes too
    late is met with just the deceleration needed. On yellow, a stop that needs more than
    `yellow_max_decel_mps2` is not attempted (drive on, as a driver would). `inf`: no bound.
    """
    d = distance_m - stop_margin_m
    if d <= 0.0:
        # Inside the margin: hold at the line, unless on yellow the line itself is too
        # close to stop at (then clear the junction, as a driver would).
        to_line = max(distance_m, 1e-6)
        too_close = speed_mps * speed_mps / (2 * to_line) > yellow_max_decel_mps2
        return math.inf if yellow and too_close else 0.0
    needed = speed_mps * speed_mps / (2 * d)
    if needed <= comfort_decel_mps2:
        return math.sqrt(2 * comfort_decel_mps2 * d)
    if yellow and needed > yellow_max_decel_mps2:
        return math.inf
    return max(speed_mps - needed * dt_s, 0.0)


def safe_following_speed(
    gap_m: float,
    leader_speed_mps: float,
    standstill_gap_m: float,
    decel_mps2: float,
    reaction_s: float,
) -> float:
    """Krauss' safe speed: after `reaction_s`, braking at `decel_mps2` still stops
    `standstill_gap_m` behind a leader that brakes as hard. Plain numbers only, compiled
    as it is for the supervisor's batch (`supervise_kernel`)."""
    room = gap_m - standstill_gap_m
    if room <= 0.0:
        return 0.0
    bt = decel_mps2 * reaction_s
    return -bt + math.sqrt(bt * bt + leader_speed_mps**2 + 2 * decel_mps2 * room)


_stop_speed_limit = njit(cache=True)(stop_speed_limit)
_safe_following_speed = njit(cache=True)(safe_following_speed)

#: Columns of `supervise_kernel`'s `situation` (NaN: none of that kind).
SITUATION_COLUMNS = (
    "signal_m", "junction_m", "lane_change_m", "vehicle_ahead_gap_m", "vehicle_ahead_mps",
    "obstacle_gap_m", "obstacle_mps", "target_leader_gap_m", "target_leader_mps",
    "signal_yellow",
)  # fmt: skip
#: Columns of `supervise_kernel`'s `config`, a row per member (1.0 / 0.0 for the rules
#: on or off; the yield rule is off for a member SUMO's junction model drives).
CONFIG_COLUMNS = (
    "signals", "yield_at_junctions", "wait_for_lane_change_gap", "emergency_braking",
    "comfort_decel_mps2", "yellow_max_decel_mps2", "stop_margin_m", "emergency_gap_m",
    "max_decel_mps2", "max_accel_mps2",
)  # fmt: skip
#: `supervise_kernel`'s states: 0 nothing enforced, then the three stops ahead in the
#: order they are met (light, minor link, lane change without a gap), then the brake.
NONE, SIGNAL, YIELD, MERGE, EMERGENCY = 0, 1, 2, 3, 4


@njit(cache=True)
def supervise_kernel(
    command_mps: np.ndarray,
    speed_mps: np.ndarray,
    dt_s: float,
    situation: np.ndarray,
    config: np.ndarray,
    asked_accel_mps2: np.ndarray,
    out_speed_mps: np.ndarray,
    out_state: np.ndarray,
    out_accel_mps2: np.ndarray,
) -> None:
    """Each member's executed speed and what the supervisor enforced
    (`supervisor.supervise_many`): the stops ahead (`situation`'s first three columns; the light's
    `signal_yellow`), then the emergency brake behind the three leaders, each lowering the speed
    only; a lowered speed is never negative. Also the acceleration the command asks for
    (`decision.desired_accel`): the controller's own figure (`asked_accel_mps2`, NaN:
    none), else the speed change within the limits."""
    for j in range(command_mps.size):
        c, s = config[j], situation[j]
        v, speed, state = speed_mps[j], command_mps[j], NONE
        asked = asked_accel_mps2[j]
        if asked == asked:
            out_accel_mps2[j] = asked
        else:
            out_accel_mps2[j] = min(max((speed - v) / dt_s, -c[8]), c[9])
        for k in range(3):
            d = s[k]
            if d != d or config[j, k] == 0.0:  # none, or the rule is off
                continue
            limit = _stop_speed_limit(d, k == 0 and s[9] != 0.0, v, dt_s, c[4], c[5], c[6])
            if speed > limit:
                speed, state = limit, k + 1
        if c[3] != 0.0:
            for k in range(3):
                gap = s[3 + 2 * k]
                if gap != gap:
                    continue
                limit = _safe_following_speed(gap, s[4 + 2 * k], c[7], c[8], dt_s)
                if speed > limit:
                    speed, state = limit, EMERGENCY
        out_speed_mps[j] = max(speed, 0.0) if state != NONE else speed
        out_state[j] = state
