"""The supervisor: traffic rules and a last-resort brake between controller and vehicle.

Every platoon vehicle's command passes through it, whatever the controller, so a
laser-only follower that trails its predecessor through a changing light still stops
at red, and no controller drives into a vehicle the loop knows is there. It only ever
lowers the commanded speed; each intervention is named in the trajectory table.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.config_loader import bounded, require_positive
from platoon_sumo.control.base import Command, Observation
from platoon_sumo.kernels.supervision import CONFIG_COLUMNS, SITUATION_COLUMNS, supervise_kernel
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import STOP_STATES, LaneChangeAhead, LinkAhead, SignalAhead, VehicleAhead


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
    """The command to execute and what (if anything) the supervisor enforced, for one
    vehicle (`supervise_many` of one)."""
    executed, enforced, _ = supervise_many(
        config_rows([config], [obs.limits], [sumo_drives]), [command],
        np.array([obs.speed_mps]), obs.dt_s, [obs.signal], [obs.link_ahead],
        [obs.lane_change], [obs.vehicle_ahead], [obs.obstacle_ahead],
    )  # fmt: skip
    return executed[0], enforced[0]


#: `kernels.supervision`'s state codes, as the trajectory table names them.
_STATES = ("", SIGNAL, YIELD, MERGE, EMERGENCY)


def config_rows(
    configs: Sequence[SupervisorConfig], limits: Sequence[MotionLimits], sumo_drives: Sequence[bool]
) -> NDArray[np.float64]:
    """`supervise_many`'s table of the members' supervisor settings and limits
    (`kernels.supervision.CONFIG_COLUMNS`), read-only: built once while the same members
    drive."""
    table = np.array(
        [
            (
                c.signals, c.yield_at_junctions and not drives, c.wait_for_lane_change_gap,
                c.emergency_braking, c.comfort_decel_mps2, c.yellow_max_decel_mps2,
                c.stop_margin_m, c.emergency_gap_m, lim.max_decel_mps2, lim.max_accel_mps2,
            )
            for c, lim, drives in zip(configs, limits, sumo_drives, strict=True)
        ],
        dtype=np.float64,
    ).reshape(len(configs), len(CONFIG_COLUMNS))  # fmt: skip
    table.flags.writeable = False
    return table


def supervise_many(
    config: NDArray[np.float64],
    commands: Sequence[Command],
    speed_mps: NDArray[np.float64],
    dt_s: float,
    signals: Sequence[SignalAhead | None],
    links: Sequence[LinkAhead | None],
    changes: Sequence[LaneChangeAhead | None],
    vehicles_ahead: Sequence[VehicleAhead | None],
    obstacles_ahead: Sequence[VehicleAhead | None],
) -> tuple[list[Command], list[str], list[float]]:
    """The commands to execute, what (if anything) the supervisor enforced on each, and
    the acceleration each command asks for (the controller's own figure, else the
    commanded speed change within the limits), for many members at once (`config`:
    their `config_rows`) in one compiled pass (`kernels.supervision`).

    Lights, minor links and lane changes without a gap are all stop points ahead, met
    with the same braking rule (`rules.stop_speed_limit`): a minor link where SUMO sees
    it closed or contested is held like a red light at the end of the lane, except for
    a member SUMO drives (lane actuation: SUMO's own junction model gives way
    underneath, with the vehicle's real approach, and holding it on top would wait out
    every permissive green while any foe approaches). The last resort is a Krauss safe
    speed at full braking, with a reaction time of one step (the brake acts on the next
    command), behind the vehicle ahead, any footprint reaching into the corridor ahead
    (`obstacle_ahead`) and, during a lane change, the vehicle ahead in the target
    lane."""
    n = len(commands)
    nan = math.nan
    situation = np.array(
        [
            (
                nan if s is None or s.state not in STOP_STATES else s.distance_m,
                nan if link is None or not link.must_yield else link.distance_m,
                nan if c is None or c.clear else c.distance_m,
                nan if a is None else a.gap_m, 0.0 if a is None else a.speed_mps,
                nan if o is None else o.gap_m, 0.0 if o is None else o.speed_mps,
                nan if (t := None if c is None else c.target_leader) is None else t.gap_m,
                0.0 if t is None else t.speed_mps,
                s is not None and s.state == "y",
            )
            for s, link, c, a, o in zip(
                signals, links, changes, vehicles_ahead, obstacles_ahead, strict=True
            )
        ],
        dtype=np.float64,
    ).reshape(n, len(SITUATION_COLUMNS))  # fmt: skip
    asked = np.array(
        [
            (
                c.speed_mps,
                nan
                if (tel := c.telemetry) is None or tel.desired_accel_mps2 is None
                else tel.desired_accel_mps2,
            )
            for c in commands
        ],
        dtype=np.float64,
    ).reshape(n, 2)
    executed_speed, states, accel = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n)
    supervise_kernel(
        asked[:, 0], speed_mps, dt_s, situation, config, asked[:, 1], executed_speed, states, accel
    )
    executed = [
        command if not state else dataclasses.replace(command, speed_mps=speed)
        for command, state, speed in zip(
            commands, states.tolist(), executed_speed.tolist(), strict=True
        )
    ]
    return executed, [_STATES[k] for k in states.tolist()], accel.tolist()
