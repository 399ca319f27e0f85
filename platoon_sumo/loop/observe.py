"""After the SUMO step: what SUMO reports (teleports, its own collisions) and the world
around the platoons, read once, in batch."""

from __future__ import annotations

from platoon_sumo.events import EventKind, Onset
from platoon_sumo.geometry import footprints_from_front_bumper
from platoon_sumo.loop.context import StepContext

#: Besides the sensors' reach, vehicles this far from a platoon vehicle are read: any
#: vehicle whose footprint could touch it (SUMO positions are front bumpers) [m].
CONTACT_REACH_M = 30.0
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
            ctx.emit(EventKind.SUMO_COLLISION, a, other=b, detail=pairs[(a, b)])


class ObserveWorld:
    """The platoon vehicles and every vehicle within the reach of their sensors (plus
    `CONTACT_REACH_M`) after the step. Nothing is read while no platoon is in the
    network."""

    def __call__(self, ctx: StepContext) -> None:
        backend = ctx.backend
        ids = ctx.fleet.ids() + [vid for vid in backend.departed_ids() if vid in ctx.waiting]
        reach = 0.0
        for m in ctx.fleet:
            for sensor in m.plan.sensors:
                reach = max(reach, float(getattr(sensor.params, "range_max_m", 0.0)))
            if not m.actuator.sumo_drives:
                reach = max(reach, LANE_CHANGE_REACH_M)
        ctx.world = backend.snapshot(ids, reach + CONTACT_REACH_M)
        ctx.sumo_vehicles = backend.vehicle_count()


class Footprints:
    """Rectangles of the world's vehicles; ours from our exact state."""

    def __call__(self, ctx: StepContext) -> None:
        world = ctx.world
        x, y, yaw = world.front_x_m.copy(), world.front_y_m.copy(), world.yaw_rad.copy()
        for m in ctx.fleet:
            i = world.index.get(m.id)
            if i is not None:
                x[i], y[i] = m.front_bumper()
                yaw[i] = m.yaw_rad
        ctx.footprints = footprints_from_front_bumper(
            x, y, yaw, world.length_m, world.width_m
        ).reshape(-1, 5)
