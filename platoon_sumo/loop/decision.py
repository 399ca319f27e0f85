"""Decisions: each member's observation, its controller (batched per class) and the
supervisor, which may only lower the speed."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.control import Controller, Observation
from platoon_sumo.control.base import ObservationColumns, ObservationRows, step_batch
from platoon_sumo.events import EventKind
from platoon_sumo.frozen import frozen_from_dict
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import LATERAL, SPEED, YAW, Member, X, Y
from platoon_sumo.path import RoutePath
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.supervisor import EMERGENCY, config_rows, supervise_many
from platoon_sumo.vehicles import MotionLimits


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


class Decide:
    def __call__(self, ctx: StepContext) -> None:
        members = ctx.fleet.members()
        if not members:
            return
        time_s, dt_s = ctx.world.time_s, ctx.dt_s
        fixed = ctx.fleet.fixed("decide", _FixedFields.of)
        kin_rows = ctx.fleet.kin[ctx.fleet.rows(members)]
        kin = kin_rows.tolist()
        scans = [m.sensors.get("laser") for m in members]
        n = len(members)
        columns = ObservationColumns(
            time_s=np.full(n, time_s), dt_s=np.full(n, dt_s),
            x_m=kin_rows[:, X], y_m=kin_rows[:, Y],
            yaw_rad=kin_rows[:, YAW], speed_mps=kin_rows[:, SPEED],
            lane_offset_m=np.where(fixed.steers, 0.0, kin_rows[:, LATERAL]),
            front_offset_m=fixed.front_offset_m, length_m=fixed.length_m,
            width_m=fixed.width_m, limits=fixed.limits, path=fixed.paths,
            scan=[s if isinstance(s, LaserScan) else None for s in scans],
            on_sumo_lanes=fixed.on_sumo_lanes, signal=[m.signal for m in members],
            vehicle_ahead=[m.vehicle_ahead for m in members],
            obstacle_ahead=[m.obstacle_ahead for m in members],
        )  # fmt: skip
        constants = fixed.constants

        def build(row: int) -> Observation:
            return observation(members[row], time_s, dt_s, kin[row], constants[row])

        observations = ObservationRows(columns, build)
        commands = step_batch(fixed.controllers, observations)
        executed, enforced, accels = supervise_many(
            fixed.supervision, commands, kin_rows[:, SPEED], dt_s, columns.signal,
            [m.link_ahead for m in members], [m.lane_change for m in members],
            columns.vehicle_ahead, columns.obstacle_ahead,
        )  # fmt: skip
        for m, command, run, state, accel, ours in zip(
            members, commands, executed, enforced, accels, fixed.ours, strict=True
        ):
            m.command, m.executed, m.desired_accel_mps2 = command, run, accel
            # SUMO's model drives a `sumo_driver` member: the supervisor's state is a
            # check there, and nothing brakes, so no emergency braking is reported
            if ours and state == EMERGENCY and m.supervisor_state != EMERGENCY:
                ctx.emit(EventKind.EMERGENCY_BRAKING, m)
            m.supervisor_state = state


@dataclass(frozen=True)
class _FixedFields:
    """What `Decide` hands on that stays the same while the same members drive."""

    constants: list[dict[str, object]]
    """Each member's `constant_fields`."""
    steers: NDArray[np.bool_]
    front_offset_m: NDArray[np.float64]
    length_m: NDArray[np.float64]
    width_m: NDArray[np.float64]
    limits: list[MotionLimits]
    paths: list[RoutePath]
    on_sumo_lanes: list[bool]
    controllers: list[Controller]
    supervision: NDArray[np.float64]
    """The members' supervisor settings and limits (`supervisor.config_rows`)."""
    ours: list[bool]
    """Whether the member's own controller drives it (not SUMO's car following)."""

    @classmethod
    def of(cls, members: Sequence[Member]) -> _FixedFields:
        constants = [constant_fields(m) for m in members]
        steers = np.array([m.actuator.steers for m in members], dtype=bool)
        front_offset, length, width = (
            _column(constants, name) for name in ("front_offset_m", "length_m", "width_m")
        )
        for shared in (steers, front_offset, length, width):  # handed on every step
            shared.flags.writeable = False
        return cls(
            constants=constants,
            steers=steers,
            front_offset_m=front_offset,
            length_m=length,
            width_m=width,
            limits=[m.platoon.limits for m in members],
            paths=[m.path for m in members],
            on_sumo_lanes=[bool(c["on_sumo_lanes"]) for c in constants],
            controllers=[m.controller for m in members],
            supervision=config_rows(
                [m.platoon.config.supervisor for m in members],
                [m.platoon.limits for m in members],
                [m.actuator.sumo_drives for m in members],
            ),
            ours=[m.plan.sumo_car_following is None for m in members],
        )


def _column(constants: list[dict[str, object]], name: str) -> NDArray[np.float64]:
    return np.array([c[name] for c in constants], dtype=np.float64)
