"""Platoons enter the network whole (or, longer than their first edge, member by member);
SUMO's arrivals and departures are booked."""

from __future__ import annotations

from platoon_sumo.actuation import ACTUATORS
from platoon_sumo.events import EventKind
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import Member
from platoon_sumo.path import RoutePath
from platoon_sumo.scenario import MemberPlan, PlatoonPlan

#: Room kept free behind the last member when a platoon is inserted [m] (the rear
#: member's follower keeps its minGap).
INSERT_ROOM_BEHIND_M = 10.0


class InsertDue:
    """Hand each due platoon to SUMO once its first lane is free from
    `INSERT_ROOM_BEHIND_M` behind its last member to `spacing_m` ahead of its leader (a
    platoon never starts scattered behind other traffic); a platoon still waiting does
    not hold back later ones. A platoon longer than its first edge has room for goes in
    with the members that fit; each of the others follows, in order, once the member
    ahead of it has departed and its slot is free in the same way."""

    def __call__(self, ctx: StepContext) -> None:
        time_s = ctx.world.time_s
        for platoon in [p for p in ctx.pending if p.config.depart_s <= time_s + 1e-9]:
            first = [m for m in platoon.members if not m.waits_for_room]
            if _room_for(ctx, platoon, first):
                ctx.pending.remove(platoon)
                _hand_over(ctx, platoon, first)
                rest = [m for m in platoon.members if m.waits_for_room]
                if rest:
                    ctx.queued[platoon.config.id] = (platoon, rest)
        for pid, (platoon, rest) in list(ctx.queued.items()):
            ahead = platoon.members[rest[0].index - 1].vehicle_id
            if ahead in ctx.waiting or not _room_for(ctx, platoon, rest[:1]):
                continue
            _hand_over(ctx, platoon, rest[:1])
            del rest[0]
            if not rest:
                del ctx.queued[pid]


def _room_for(ctx: StepContext, platoon: PlatoonPlan, members: list[MemberPlan]) -> bool:
    """The first lane is free from `INSERT_ROOM_BEHIND_M` behind the last of `members`
    to `spacing_m` ahead of the first."""
    cfg = platoon.config
    front = members[0].depart_pos_m
    rear = members[-1].depart_pos_m - cfg.vehicle.length_m
    lane = f"{platoon.edges[0]}_{platoon.depart_lane}"
    return ctx.backend.lane_is_free(lane, rear - INSERT_ROOM_BEHIND_M, front + cfg.spacing_m)


def _hand_over(ctx: StepContext, platoon: PlatoonPlan, members: list[MemberPlan]) -> None:
    actuator = ACTUATORS.get(platoon.config.actuation_name)
    for member in members:
        ctx.backend.add_vehicle(
            member.vehicle_id, platoon.edges, platoon.type_id_of(member), platoon.depart_lane,
            member.depart_pos_m, sumo_drives=actuator.sumo_drives, steers=actuator.steers,
        )  # fmt: skip
        ctx.waiting[member.vehicle_id] = member


class RemovedElsewhere:
    """Platoon vehicles taken out of SUMO between two steps by someone else (a hook or
    plug-in calling libsumo) leave the fleet, reported as removed."""

    def __call__(self, ctx: StepContext) -> None:
        for vid in ctx.backend.removed_elsewhere():
            ctx.waiting.pop(vid, None)
            member = ctx.fleet.remove(vid)
            if member is not None:
                ctx.emit(EventKind.REMOVED, member, detail="taken out of SUMO outside the loop")


class Arrivals:
    """Vehicles SUMO let arrive leave the fleet."""

    def __call__(self, ctx: StepContext) -> None:
        arrived = ctx.backend.arrived_ids()
        ctx.arrived_total += len(arrived)
        for vid in arrived:
            member = ctx.fleet.remove(vid)
            if member is not None:
                ctx.emit(EventKind.ARRIVED, member)


class Departures:
    """Members SUMO inserted join the fleet: pose from SUMO at speed 0, a fresh
    controller, the route path (shared per route), the first projection."""

    def __init__(self) -> None:
        self._paths: dict[tuple[str, ...], RoutePath] = {}

    def __call__(self, ctx: StepContext) -> None:
        departed = ctx.backend.departed_ids()
        ctx.departed_total += len(departed)
        world = ctx.world
        new: list[Member] = []
        for vid in departed:
            plan = ctx.waiting.pop(vid, None)
            if plan is None:
                continue
            platoon = next(p for p in ctx.run.plan.platoons if p.config.id == plan.platoon_id)
            controller = plan.controller_cls(plan.controller_params)
            controller.reset()
            i = world.index[vid]
            member = ctx.fleet.join(
                plan, platoon, controller, ACTUATORS.get(platoon.config.actuation_name)(),
                self._path_for(ctx, platoon),
            )  # fmt: skip
            member.set_front_pose(
                float(world.front_x_m[i]), float(world.front_y_m[i]), float(world.yaw_rad[i])
            )
            fx, fy = member.front_bumper()
            point = member.path.project(fx, fy)
            member.route_s_m, member.lateral_offset_m = point.s_m, point.lateral_offset_m
            ctx.emit(EventKind.DEPARTED, member)
            new.append(member)
        if new:  # the light ahead at departure: the red-light check compares with it
            ids = [m.id for m in new]
            contexts = ctx.backend.route_contexts(ids, [0.0] * len(new), [False] * len(new))
            for member, (signal, _, _) in zip(new, contexts, strict=True):
                member.signal = signal

    def _path_for(self, ctx: StepContext, platoon: PlatoonPlan) -> RoutePath:
        cfg = platoon.config
        key = (*platoon.edges, str(platoon.depart_lane), str(cfg.vehicle.length_m))
        if key not in self._paths:
            spacing = min(max(cfg.vehicle.length_m / 8, 0.02), 0.5)
            self._paths[key] = ctx.run.plan.network.route_path(
                platoon.edges, spacing_m=spacing, first_lane=platoon.depart_lane,
                vclass=cfg.vehicle.vclass,
            )  # fmt: skip
        return self._paths[key]
