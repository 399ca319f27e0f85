"""REFERENCE ONLY (test oracle): ``platoon_sumo/supervisor.py``'s check of one vehicle
as it was before the supervisor became one compiled pass over all members
(``platoon_sumo.kernels.supervision``), kept so ``test_supervisor.py`` can compare the
batch with it. Changes from the original: the desired acceleration the loop worked out
beside it (``loop/decision.py``'s ``desired_accel``) is returned with it. Do not use in
package code, do not change.
"""

from __future__ import annotations

import dataclasses

from platoon_sumo.control.base import Command
from platoon_sumo.control.rules import safe_following_speed, signal_speed_limit
from platoon_sumo.supervisor import EMERGENCY, MERGE, SIGNAL, YIELD, SupervisorConfig
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import LaneChangeAhead, LinkAhead, SignalAhead, VehicleAhead


def supervise_fields(
    config: SupervisorConfig,
    command: Command,
    speed_mps: float,
    dt_s: float,
    limits: MotionLimits,
    signal: SignalAhead | None,
    link: LinkAhead | None,
    change: LaneChangeAhead | None,
    vehicle_ahead: VehicleAhead | None,
    obstacle_ahead: VehicleAhead | None,
    sumo_drives: bool = False,
) -> tuple[Command, str, float]:
    stops: list[tuple[SignalAhead | None, str]] = []
    if config.signals:
        stops.append((signal, SIGNAL))
    if config.yield_at_junctions and not sumo_drives and link is not None and link.must_yield:
        stops.append((SignalAhead("junction", -1, "r", link.distance_m), YIELD))
    if config.wait_for_lane_change_gap and change is not None and not change.clear:
        stops.append((SignalAhead("lane change", -1, "r", change.distance_m), MERGE))
    speed, state = command.speed_mps, ""
    for stop, reason in stops:
        limit = signal_speed_limit(
            stop, speed_mps, dt_s, config.comfort_decel_mps2, config.yellow_max_decel_mps2,
            config.stop_margin_m,
        )  # fmt: skip
        if speed > limit:
            speed, state = limit, reason
    leaders = [vehicle_ahead, obstacle_ahead, change.target_leader if change is not None else None]
    for ahead in leaders if config.emergency_braking else ():
        if ahead is None:
            continue
        limit = safe_following_speed(
            ahead.gap_m, ahead.speed_mps, config.emergency_gap_m, limits.max_decel_mps2, dt_s
        )
        if speed > limit:
            speed, state = limit, EMERGENCY
    accel = _desired_accel(command, dt_s, speed_mps, limits)
    if not state:
        return command, "", accel
    return dataclasses.replace(command, speed_mps=max(speed, 0.0)), state, accel


def _desired_accel(command: Command, dt_s: float, speed_mps: float, limits: MotionLimits) -> float:
    telemetry = command.telemetry
    if telemetry is not None and telemetry.desired_accel_mps2 is not None:
        return float(telemetry.desired_accel_mps2)
    wanted = (command.speed_mps - speed_mps) / dt_s
    return min(max(wanted, -limits.max_decel_mps2), limits.max_accel_mps2)
