"""Speed bounds every careful driver obeys, shared by controllers and the supervisor.

Pure functions of the situation, so a controller can plan with them comfortably and
the supervisor can enforce them as a last resort with the same arithmetic.
"""

from __future__ import annotations

import math

from platoon_sumo.world import SignalAhead


def signal_speed_limit(
    signal: SignalAhead | None,
    speed_mps: float,
    dt_s: float,
    comfort_decel_mps2: float,
    yellow_max_decel_mps2: float,
    stop_margin_m: float,
) -> float:
    """Highest speed that still stops `stop_margin_m` before a red or yellow stop line.

    Braking starts when the comfortable deceleration is needed; a light that changes too
    late is met with just the deceleration needed. On yellow, a stop that needs more than
    `yellow_max_decel_mps2` is not attempted (drive on, as a driver would). `inf`: no bound.
    """
    if signal is None or not signal.is_stop:
        return math.inf
    d = signal.distance_m - stop_margin_m
    if d <= 0.0:
        # Inside the margin: hold at the line, unless on yellow the line itself is too
        # close to stop at (then clear the junction, as a driver would).
        to_line = max(signal.distance_m, 1e-6)
        too_close = speed_mps * speed_mps / (2 * to_line) > yellow_max_decel_mps2
        return math.inf if signal.state == "y" and too_close else 0.0
    needed = speed_mps * speed_mps / (2 * d)
    if needed <= comfort_decel_mps2:
        return math.sqrt(2 * comfort_decel_mps2 * d)
    if signal.state == "y" and needed > yellow_max_decel_mps2:
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
    `standstill_gap_m` behind a leader that brakes as hard."""
    room = gap_m - standstill_gap_m
    if room <= 0.0:
        return 0.0
    bt = decel_mps2 * reaction_s
    return -bt + math.sqrt(bt * bt + leader_speed_mps**2 + 2 * decel_mps2 * room)
