"""Decisions: each member's observation, its controller (batched per class) and the
supervisor, which may only lower the speed."""

from __future__ import annotations

from platoon_sumo.control import Command, Observation
from platoon_sumo.control.base import step_batch
from platoon_sumo.events import EventKind
from platoon_sumo.frozen import frozen_from_dict
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import LATERAL, SPEED, YAW, Member, X, Y
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.supervisor import EMERGENCY, supervise


def constant_fields(m: Member) -> dict[str, object]:
    """The fields of `m`'s observations that stay the same for its whole run."""
    cfg = m.platoon.config.vehicle
    return {
        "vehicle_id": m.id,
        "role": m.plan.role,
        "front_offset_m": cfg.front_offset_m,
        "length_m": cfg.length_m,
        "width_m": cfg.width_m,
        "limits": m.platoon.limits,
        "on_sumo_lanes": m.actuator.sumo_drives,
        "platoon_id": m.platoon_id,
        "index": m.index,
    }


def observation(
    m: Member, time_s: float, dt_s: float, kin: list[float], constants: dict[str, object]
) -> Observation:
    """What a controller sees: odometry (`kin`, its row of the fleet's state), its route,
    SUMO's view of the road ahead (read after the previous step) and its sensors' latest
    messages; `constants` are its `constant_fields`."""
    scan = m.sensors.get("laser")
    return frozen_from_dict(Observation, {
        **constants,
        "time_s": time_s,
        "dt_s": dt_s,
        "x_m": kin[X],
        "y_m": kin[Y],
        "yaw_rad": kin[YAW],
        "speed_mps": kin[SPEED],
        "path": m.path,
        "lane_offset_m": 0.0 if m.actuator.steers else kin[LATERAL],
        "signal": m.signal,
        "link_ahead": m.link_ahead,
        "lane_change": m.lane_change,
        "vehicle_ahead": m.vehicle_ahead,
        "obstacle_ahead": m.obstacle_ahead,
        "scan": scan if isinstance(scan, LaserScan) else None,
        "sensors": dict(m.sensors),
    })  # fmt: skip


def desired_accel(m: Member, command: Command, dt_s: float, speed_mps: float) -> float:
    """The controller's own figure, else the commanded speed change within the limits."""
    telemetry = command.telemetry
    if telemetry is not None and telemetry.desired_accel_mps2 is not None:
        return float(telemetry.desired_accel_mps2)
    limits = m.platoon.limits
    wanted = (command.speed_mps - speed_mps) / dt_s
    return min(max(wanted, -limits.max_decel_mps2), limits.max_accel_mps2)


class Decide:
    def __init__(self) -> None:
        self._constants: dict[str, tuple[Member, dict[str, object]]] = {}
        """Each member's `constant_fields`, by id (with the member they were made for)."""

    def _constant_fields(self, m: Member) -> dict[str, object]:
        known = self._constants.get(m.id)
        if known is None or known[0] is not m:
            known = self._constants[m.id] = (m, constant_fields(m))
        return known[1]

    def __call__(self, ctx: StepContext) -> None:
        members = list(ctx.fleet)
        if not members:
            return
        time_s = ctx.world.time_s
        kin = ctx.fleet.kin[ctx.fleet.rows(members)].tolist()
        observations = [
            observation(m, time_s, ctx.dt_s, k, self._constant_fields(m))
            for m, k in zip(members, kin, strict=True)
        ]
        commands = step_batch([m.controller for m in members], observations)
        for m, obs, command in zip(members, observations, commands, strict=True):
            m.command = command
            m.desired_accel_mps2 = desired_accel(m, command, ctx.dt_s, obs.speed_mps)
            m.executed, enforced = supervise(
                m.platoon.config.supervisor, obs, command, m.actuator.sumo_drives
            )
            # SUMO's model drives a `sumo_driver` member: the supervisor's state is a
            # check there, and nothing brakes, so no emergency braking is reported
            ours = m.plan.sumo_car_following is None
            if ours and enforced == EMERGENCY and m.supervisor_state != EMERGENCY:
                ctx.emit(EventKind.EMERGENCY_BRAKING, m)
            m.supervisor_state = enforced
