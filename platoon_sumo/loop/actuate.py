"""Actuation: each platoon's executed commands go to its actuator (planar or lane, see
`platoon_sumo.actuation`); after the SUMO step, SUMO-driven members are read back."""

from __future__ import annotations

import numpy as np

from platoon_sumo.actuation import ActuationBatch
from platoon_sumo.events import EventKind
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import Member
from platoon_sumo.supervisor import SUMO_SAFETY
from platoon_sumo.vehicles import KinematicState, heading_to_yaw_rate

#: SUMO's speed this far below what the command and the acceleration limit allowed
#: means SUMO's safety layer acted [m/s].
SUMO_CAP_TOLERANCE_MPS = 0.01


def _yaw_rate(m: Member, dt_s: float) -> float:
    cmd = m.executed
    if cmd.heading_rad is None:
        return cmd.yaw_rate_radps
    limit = m.platoon.limits.max_yaw_rate_radps
    return float(heading_to_yaw_rate(cmd.heading_rad, m.yaw_rad, dt_s, limit)[0])


class Actuate:
    def __call__(self, ctx: StepContext) -> None:
        for group in ctx.fleet.by_platoon().values():
            platoon, actuator = group[0].platoon, group[0].actuator
            state = KinematicState.of(
                [m.x_m for m in group], [m.y_m for m in group],
                [m.yaw_rad for m in group], [m.speed_mps for m in group],
            )  # fmt: skip
            batch = ActuationBatch(
                vehicle_ids=tuple(m.id for m in group),
                state=state,
                speed_cmd_mps=np.array([m.executed.speed_mps for m in group]),
                yaw_rate_cmd_radps=np.array([_yaw_rate(m, ctx.dt_s) for m in group]),
                lane_change=np.array([m.executed.lane_change for m in group], dtype=np.int64),
                front_offset_m=platoon.config.vehicle.front_offset_m,
                limits=platoon.limits,
                model=platoon.model(),
                dt_s=ctx.dt_s,
            )
            result = actuator.apply(batch, ctx.backend)
            if result.state is not None:
                new = result.state
                for k, m in enumerate(group):
                    speed = float(new.speed_mps[k])
                    m.accel_mps2 = (speed - m.speed_mps) / ctx.dt_s
                    m.x_m, m.y_m = float(new.x_m[k]), float(new.y_m[k])
                    m.yaw_rad, m.speed_mps = float(new.yaw_rad[k]), speed
            for m in group:  # off its route: out of the run, reported
                reason = result.failed.get(m.id)
                if reason is not None:
                    ctx.remove(m, arrived=False, reason=reason)


class ReadBack:
    """Lane actuation: SUMO moved the vehicle, its pose and speed become the state.

    Where SUMO's speed stays clearly below what the executed command and the
    acceleration limit allowed, SUMO's safety layer acted: named in the supervisor state
    and counted once per episode."""

    def __call__(self, ctx: StepContext) -> None:
        world = ctx.world
        for m in ctx.fleet:
            i = world.index.get(m.id)
            if not m.actuator.sumo_drives or i is None:
                continue
            speed = float(world.speed_mps[i])
            previous = m.speed_mps
            m.set_front_pose(
                float(world.front_x_m[i]), float(world.front_y_m[i]), float(world.yaw_rad[i])
            )
            m.speed_mps = speed
            m.accel_mps2 = (speed - previous) / ctx.dt_s
            allowed = min(
                m.executed.speed_mps, previous + m.platoon.limits.max_accel_mps2 * ctx.dt_s
            )
            capped = speed < allowed - SUMO_CAP_TOLERANCE_MPS
            if capped and not m.sumo_capped:
                ctx.emit(EventKind.SUMO_SPEED_CAP, m)
            m.sumo_capped = capped
            if capped and not m.supervisor_state:
                m.supervisor_state = SUMO_SAFETY
