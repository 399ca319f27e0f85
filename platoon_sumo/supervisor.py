"""The supervisor: traffic rules and a last-resort brake between controller and vehicle.

Every platoon vehicle's command passes through it, whatever the controller, so a
laser-only follower that trails its predecessor through a changing light still stops
at red, and no controller drives into a vehicle the loop knows is there. It only ever
lowers the commanded speed; each intervention is named in the trajectory table.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from platoon_sumo.config_loader import bounded, require_positive
from platoon_sumo.control.base import Command, Observation
from platoon_sumo.control.rules import safe_following_speed, signal_speed_limit
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import LaneChangeAhead, LinkAhead, SignalAhead, VehicleAhead


@dataclass(frozen=True)
class SupervisorConfig:
    signals: bool = True
    """Stop for red and yellow lights when the stop is possible."""
    comfort_decel_mps2: float = bounded(2.5, gt=0, le=50)
    """Deceleration used to stop at a light [m/s²]."""
    yellow_max_decel_mps2: float = bounded(4.0, gt=0, le=50)
    """On yellow, stop only if it takes at most this deceleration [m/s²]."""
    stop_margin_m: float = bounded(0.5, ge=0, le=100)
    """Front bumper stops this far before the stop line [m]."""
    yield_at_junctions: bool = True
    """Planar actuation: on a minor approach, stop before the junction while SUMO sees it
    closed or contested. (Lane actuation leaves it to SUMO's junction model.)"""
    wait_for_lane_change_gap: bool = True
    """Before a lane change of the route, wait (slow down, or stop where it begins) until
    the target lane has a gap; during the move, pause the sideways motion while a vehicle
    on the target lane is alongside or about to be."""
    emergency_braking: bool = True
    """Brake at full capability when the vehicle ahead (SUMO's ground truth) is too close."""
    emergency_gap_m: float = bounded(0.5, ge=0, le=100)
    """Standstill gap the emergency brake protects [m]; robots want a few centimetres."""

    def __post_init__(self) -> None:
        require_positive(self, "comfort_decel_mps2", "yellow_max_decel_mps2")
        require_positive(self, "stop_margin_m", "emergency_gap_m", allow_zero=True)


#: Supervisor states recorded per step ("" when the controller's command passed unchanged).
SIGNAL, YIELD, MERGE, EMERGENCY = "signal", "yield", "merge", "emergency"
#: Recorded by the loop, not set here: with lane actuation SUMO's own safety layer held
#: the vehicle below the command the supervisor let through.
SUMO_SAFETY = "sumo"


def supervise(
    config: SupervisorConfig, obs: Observation, command: Command, sumo_drives: bool = False
) -> tuple[Command, str]:
    """The command to execute and what (if anything) the supervisor enforced
    (`supervise_fields` of the observation's fields)."""
    return supervise_fields(
        config, command, obs.speed_mps, obs.dt_s, obs.limits, obs.signal, obs.link_ahead,
        obs.lane_change, obs.vehicle_ahead, obs.obstacle_ahead, sumo_drives,
    )  # fmt: skip


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
) -> tuple[Command, str]:
    """The command to execute and what (if anything) the supervisor enforced, from the
    fields of the vehicle's `Observation` it reads (the loop passes them without
    building one).

    `sumo_drives` (lane actuation): SUMO's own junction model gives way underneath, with
    this vehicle's real approach (arrival time and speed), so the supervisor does not
    hold the vehicle at minor links on top of it (it would wait out every permissive
    green while any foe approaches).

    Lights, minor links and lane changes without a gap are all stop points ahead, met
    with the same braking rule (`signal_speed_limit`); the last resort is a Krauss safe
    speed at full braking behind the vehicle ahead, any footprint reaching into the
    corridor ahead (`obstacle_ahead`) and, during a lane change, the vehicle ahead in the
    target lane."""
    stops: list[tuple[SignalAhead | None, str]] = []
    if config.signals:
        stops.append((signal, SIGNAL))
    if config.yield_at_junctions and not sumo_drives and link is not None and link.must_yield:
        # held like a red light at the end of the lane until SUMO opens the link
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
        # Reaction time of one step: the brake acts on the next command.
        limit = safe_following_speed(
            ahead.gap_m, ahead.speed_mps, config.emergency_gap_m, limits.max_decel_mps2, dt_s
        )
        if speed > limit:
            speed, state = limit, EMERGENCY
    if not state:
        return command, ""
    return dataclasses.replace(command, speed_mps=max(speed, 0.0)), state
