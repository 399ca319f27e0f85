"""After the SUMO step: what SUMO reports (teleports, its own collisions) and the world
around the platoons, read once, in batch."""

from __future__ import annotations

import numpy as np

from platoon_sumo.actuation import ACTUATORS
from platoon_sumo.events import EventKind, Onset
from platoon_sumo.geometry import footprints_from_front_bumper
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import YAW
from platoon_sumo.scenario import RunPlan

#: Planar lane changes look this far along the target lanes for gaps [m].
LANE_CHANGE_REACH_M = 100.0


class SumoReports:
    """Teleports and SUMO's own (lane-based) collision reports; a collision counts once
    per (collider, victim) contact, when it begins."""

    def __init__(self) -> None:
        self._contacts: Onset[tuple[str, str]] = Onset()

    def __call__(self, ctx: StepContext) -> None:
        for vid in ctx.backend.teleported_ids():
            ctx.emit(EventKind.TELEPORT, vid)
        pairs = {(a, b): kind for a, b, kind in sorted(ctx.backend.sumo_collisions())}
        for a, b in self._contacts.update(pairs):
            ctx.emit(EventKind.SUMO_COLLISION, a, other=b, detail=pairs[(a, b)], at_fault=a)


class Gridlocks:
    """Every `CHECK_EVERY_S` simulated seconds: vehicles (any) standing still for
    `outputs.gridlock_after_s`, neither at a stop of their schedule nor queued at a red
    light; each such vehicle is one `gridlock` event when it is first found so (again
    after it has moved). Where: its lane and position, in the event's detail."""

    CHECK_EVERY_S = 10.0

    def __init__(self) -> None:
        self._standing: Onset[str] = Onset()

    def __call__(self, ctx: StepContext) -> None:
        after_s = ctx.run.plan.scenario.outputs.gridlock_after_s
        every = max(1, round(self.CHECK_EVERY_S / ctx.dt_s))
        if after_s is None or ctx.steps % every:
            return
        standing = {vid: rest for vid, *rest in ctx.backend.standing_vehicles(after_s)}
        for vid in self._standing.update(standing):
            lane, x, y, waited = standing[vid]
            member = ctx.fleet.get(vid)
            ctx.emit(
                EventKind.GRIDLOCK, member if member is not None else vid,
                detail=f"lane {lane} at ({x:.1f}, {y:.1f}), still for {waited:.0f} s",
            )  # fmt: skip


class ObserveWorld:
    """The platoon vehicles and every vehicle that one of their sensors could see or
    whose footprint could touch one of them, after the step. Positions are front
    bumpers, so the radius around each platoon vehicle's front bumper is the longest
    sensor range (or planar lane changes' look-out) plus the largest platoon vehicle and
    the largest vehicle that entered the network (length + width each: a sensor may sit
    anywhere on its car, a body reaches a length behind its front bumper). Nothing is
    read while no platoon is in the network."""

    def __init__(self) -> None:
        self._own_reach_m: float | None = None

    def __call__(self, ctx: StepContext) -> None:
        backend = ctx.backend
        ids = ctx.fleet.ids() + [vid for vid in backend.departed_ids() if vid in ctx.waiting]
        radius = 0.0
        if ids:
            if self._own_reach_m is None:
                self._own_reach_m = own_reach_m(ctx.run.plan)
            radius = self._own_reach_m + backend.largest_vehicle_m()
        ctx.world_before, ctx.world = ctx.world, backend.snapshot(ids, radius)


def own_reach_m(plan: RunPlan) -> float:
    """Longest sensor range (or planar look-out) plus the largest platoon vehicle [m]."""
    reach = size = 0.0
    for platoon in plan.platoons:
        vehicle = platoon.config.vehicle
        size = max(size, vehicle.length_m + vehicle.width_m)
        if ACTUATORS.get(platoon.config.actuation_name).steers:
            reach = max(reach, LANE_CHANGE_REACH_M)
        for member in platoon.members:
            for sensor in member.sensors:
                reach = max(reach, float(getattr(sensor.params, "range_max_m", 0.0)))
    return reach + size


class Footprints:
    """Rectangles of the world's vehicles; ours from our exact state."""

    def __call__(self, ctx: StepContext) -> None:
        world, fleet = ctx.world, ctx.fleet
        x, y, yaw = world.front_x_m.copy(), world.front_y_m.copy(), world.yaw_rad.copy()
        ours = [m for m in fleet if m.id in world.index]
        if ours:
            at = np.fromiter((world.index[m.id] for m in ours), dtype=np.int64, count=len(ours))
            rows = fleet.rows(ours)
            x[at], y[at] = fleet.front_bumpers(rows)
            yaw[at] = fleet.kin[rows, YAW]
        ctx.footprints = footprints_from_front_bumper(
            x, y, yaw, world.length_m, world.width_m
        ).reshape(-1, 5)
