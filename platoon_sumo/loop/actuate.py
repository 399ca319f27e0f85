"""Actuation: each platoon's executed commands pass its powertrain (actuator lag and jerk
bound, `vehicles.powertrain_speed`) and go to its actuator (planar, lane or sublane, see
`platoon_sumo.actuation`), except the speed of a member whose controller leaves it to
SUMO's car-following model (`sumo_driver`); after the SUMO step, SUMO-driven members are
read back."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.actuation import ActuationBatch, Surroundings
from platoon_sumo.errors import PlatoonSumoError, PluginError
from platoon_sumo.events import EventKind
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import ACCEL, SPEED, YAW, Member, X, Y
from platoon_sumo.supervisor import SUMO_SAFETY
from platoon_sumo.vehicles import KinematicState, heading_to_yaw_rate, powertrain_speed
from platoon_sumo.world import yaw_rates

#: SUMO's speed this far below what the command and the acceleration limit allowed
#: means SUMO's safety layer acted [m/s].
SUMO_CAP_TOLERANCE_MPS = 0.01
#: The speed sent for a member whose controller leaves the speed to SUMO's
#: car-following model: SUMO's `setSpeed(-1)`, its own model again (never below what
#: SUMO drove, so never a SUMO cap in `ReadBack`).
SUMO_DECIDES = -1.0

FloatArray = NDArray[np.float64]


def _yaw_rate(m: Member, dt_s: float) -> float:
    cmd = m.executed
    if cmd.heading_rad is None:
        return cmd.yaw_rate_radps
    limit = m.platoon.limits.max_yaw_rate_radps
    return float(heading_to_yaw_rate(cmd.heading_rad, m.yaw_rad, dt_s, limit)[0])


class Actuate:
    """One actuator call per group of platoons that share the actuation mode, vehicle,
    limits and model (usually one call for the whole fleet); the group's first member's
    actuator instance is called."""

    def __init__(self) -> None:
        self._group_of: dict[tuple[str, type], int] = {}
        """(platoon, actuator class) -> its group's number: the group's key hashes
        frozen configurations of about 20 fields, so it is worked out once a platoon."""
        self._groups: dict[tuple[object, ...], int] = {}

    def __call__(self, ctx: StepContext) -> None:
        world = ctx.world
        footprints = ctx.footprints if len(ctx.footprints) == len(world) else None
        for group in ctx.fleet.fixed((self, "groups"), self._grouped):
            self._apply(ctx, group, footprints)

    def _grouped(self, members: Sequence[Member]) -> list[_Group]:
        groups: dict[int, list[Member]] = {}
        group_of = self._group_of
        for m in members:
            kind = (m.platoon_id, type(m.actuator))
            number = group_of.get(kind)
            if number is None:
                p = m.platoon
                key = (type(m.actuator), p.config.vehicle, p.limits, p.model)
                number = group_of[kind] = self._groups.setdefault(key, len(self._groups))
            groups.setdefault(number, []).append(m)
        return [_Group.of(group) for group in groups.values()]

    @staticmethod
    def _apply(ctx: StepContext, g: _Group, footprints: FloatArray | None) -> None:
        fleet, dt_s, world = ctx.fleet, ctx.dt_s, ctx.world
        group, rows = g.members, g.rows
        platoon, actuator = group[0].platoon, group[0].actuator
        vehicle = platoon.config.vehicle
        kin = fleet.kin[rows]
        executed = [m.executed for m in group]
        speed_cmd = np.array([c.speed_mps for c in executed])
        powertrain = vehicle.powertrain()
        if not powertrain.is_ideal:
            speed_cmd = powertrain_speed(
                kin[:, SPEED], kin[:, ACCEL], speed_cmd, powertrain, platoon.limits, dt_s
            )
        # SUMO's car-following model decides these members' speed (`sumo_driver`)
        speed_cmd[g.by_sumo] = SUMO_DECIDES
        for m, sent in zip(group, speed_cmd.tolist(), strict=True):
            m.speed_sent_mps = sent
        batch = ActuationBatch(
            vehicle_ids=g.ids,
            state=KinematicState(kin[:, X], kin[:, Y], kin[:, YAW], kin[:, SPEED]),
            speed_cmd_mps=speed_cmd,
            yaw_rate_cmd_radps=np.array([_yaw_rate(m, dt_s) for m in group]),
            lane_change=np.array([c.lane_change for c in executed], dtype=np.int64),
            keep_lane=np.array([c.keep_lane for c in executed], dtype=bool),
            sidestep_m=np.array([m.sidestep_m for m in group]) if actuator.steers else None,
            surroundings=None
            if footprints is None or not actuator.steers
            else Surroundings(
                footprints,
                world.speed_mps,
                yaw_rates(world, ctx.world_before),
                np.array([world.index.get(m.id, -1) for m in group], dtype=np.int64),
            ),
            front_offset_m=vehicle.front_offset_m,
            length_m=vehicle.length_m,
            limits=platoon.limits,
            model=platoon.model(),
            dt_s=dt_s,
        )
        try:
            result = actuator.apply(batch, ctx.backend)
        except PlatoonSumoError:
            raise
        except Exception as exc:
            cls = type(actuator)
            platoons = ", ".join(dict.fromkeys(f"'{m.platoon_id}'" for m in group))
            raise PluginError(
                f"actuator {cls.__module__}.{cls.__qualname__} of platoon {platoons} "
                f"(vehicles {', '.join(batch.vehicle_ids[:3])}) failed at "
                f"t={ctx.world.time_s:.2f} s: {type(exc).__name__}: {exc}"
            ) from exc
        if result.state is not None:
            new = result.state
            fleet.kin[rows, ACCEL] = (new.speed_mps - kin[:, SPEED]) / dt_s
            fleet.kin[rows, X], fleet.kin[rows, Y] = new.x_m, new.y_m
            fleet.kin[rows, YAW], fleet.kin[rows, SPEED] = new.yaw_rad, new.speed_mps
        for m in group:  # off its route: out of the run, reported
            reason = result.failed.get(m.id)
            if reason is not None:
                ctx.remove(m, arrived=False, reason=reason)


class ReadBack:
    """Lane actuation: SUMO moved the vehicle, its pose and speed become the state.

    Where SUMO's speed stays clearly below what the speed sent (the executed command
    after the powertrain) and the acceleration limit allowed, SUMO's safety layer
    acted: named in the supervisor state and counted once per episode."""

    def __call__(self, ctx: StepContext) -> None:
        world, fleet, dt_s = ctx.world, ctx.fleet, ctx.dt_s
        index = world.index
        group = [m for m in fleet if m.actuator.sumo_drives and m.id in index]
        if not group:
            return
        at = np.fromiter((index[m.id] for m in group), dtype=np.int64, count=len(group))
        rows = fleet.rows(group)
        previous = fleet.kin[rows, SPEED]
        speed = world.speed_mps[at]
        fleet.set_front_poses(rows, world.front_x_m[at], world.front_y_m[at], world.yaw_rad[at])
        fleet.kin[rows, SPEED] = speed
        fleet.kin[rows, ACCEL] = (speed - previous) / dt_s
        commanded = np.array([m.speed_sent_mps for m in group])
        max_accel = np.array([m.platoon.limits.max_accel_mps2 for m in group])
        allowed = np.minimum(commanded, previous + max_accel * dt_s)
        capped = speed < allowed - SUMO_CAP_TOLERANCE_MPS
        for m, is_capped in zip(group, capped.tolist(), strict=True):
            if is_capped and not m.sumo_capped:
                ctx.emit(EventKind.SUMO_SPEED_CAP, m)
            m.sumo_capped = is_capped
            if is_capped and not m.supervisor_state:
                m.supervisor_state = SUMO_SAFETY


@dataclass(frozen=True)
class _Group:
    """Members one actuator call moves, and what stays the same about them while the
    same members drive."""

    members: list[Member]
    rows: NDArray[np.int64]
    ids: tuple[str, ...]
    by_sumo: NDArray[np.bool_]
    """Whose speed SUMO's car-following model decides (`sumo_driver`)."""

    @classmethod
    def of(cls, members: list[Member]) -> _Group:
        rows = np.fromiter((m.row for m in members), dtype=np.int64, count=len(members))
        by_sumo = np.array([m.plan.sumo_car_following is not None for m in members], dtype=bool)
        for shared in (rows, by_sumo):
            shared.flags.writeable = False
        return cls(members, rows, tuple(m.id for m in members), by_sumo)
