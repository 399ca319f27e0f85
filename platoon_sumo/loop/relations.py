"""Ground truth about the platoons after the step: predecessors and true gaps, the
platoon's cohesion (splits, re-formations, cut-ins) and contacts. Metrics only: no
controller reads any of it."""

from __future__ import annotations

import numpy as np

from platoon_sumo.events import WALL, EventKind, Onset
from platoon_sumo.fault import PLACED_REACTION_S, contact_fault, was_placed
from platoon_sumo.geometry import (
    CX,
    CY,
    LENGTH,
    YAW,
    centre_to_front_bumper,
    rectangle_corners,
    rectangles_crossing_segments,
    wrap_angle,
)
from platoon_sumo.kernels.rectangles import overlapping_pairs_kernel
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.ports import FloatArray
from platoon_sumo.platoon import LinkMonitor, bumper_gap_m, predecessor_ids
from platoon_sumo.sumo.network import Network


class Predecessors:
    """Each member's predecessor (the nearest member ahead still in the network) and
    the bumper gap to it, measured on the footprints."""

    def __call__(self, ctx: StepContext) -> None:
        members = ctx.fleet.members()
        predecessors = ctx.fleet.fixed("predecessors", predecessor_ids)
        index = ctx.world.index
        pairs: list[tuple[int, int]] = []
        measured = []
        for m in members:
            pred = predecessors[m.id]
            m.predecessor_id = pred
            m.gap_to_predecessor_m = None
            if pred is not None and pred in index and m.id in index:
                pairs.append((index[m.id], index[pred]))
                measured.append(m)
        if measured:  # the footprints as Python floats: math on numpy scalars is 4x dearer
            rects = ctx.footprints[np.array(pairs, dtype=np.int64)].tolist()
            for m, (own, ahead) in zip(measured, rects, strict=True):
                m.gap_to_predecessor_m = bumper_gap_m(own, ahead)


class Cohesion:
    """Splits, re-formations and cut-ins from what each follower perceives: with a laser,
    linked while its last scan had rays on the predecessor; without, while the true gap
    is at most `split_gap_m`."""

    def __init__(self, hold_s: float = 1.0) -> None:
        self.monitor = LinkMonitor(hold_s)
        self._linked: dict[str, bool] = {}

    def __call__(self, ctx: StepContext) -> None:
        time_s = ctx.world.time_s
        present = set()
        for m in ctx.fleet:
            present.add(m.id)
            pred = m.predecessor_id
            if pred is None:
                continue
            if m.plan.laser is not None:
                if m.predecessor_rays is not None:  # keep the last verdict between scans
                    self._linked[m.id] = m.predecessor_rays > 0
            else:
                gap = m.gap_to_predecessor_m
                self._linked[m.id] = gap is not None and gap <= m.platoon.config.split_gap_m
            ahead = m.vehicle_ahead
            intruder = None
            if (
                ahead is not None
                and not ahead.vehicle_id.startswith(m.platoon_id + ".")
                and (m.gap_to_predecessor_m is None or ahead.gap_m < m.gap_to_predecessor_m)
            ):
                intruder = ahead.vehicle_id
            for e in self.monitor.observe(
                time_s, m.platoon_id, m.id, pred, self._linked.get(m.id, False), intruder
            ):
                kind = {"split": EventKind.SPLIT, "reformation": EventKind.REFORMATION}.get(
                    e.kind, EventKind.CUT_IN
                )
                ctx.emit(kind, m, other=e.other_id)
        for gone in set(self._linked) - present:  # bounded memory: forget who left
            del self._linked[gone]
            self.monitor.forget(gone)


class SafetyCheck:
    """Footprint overlaps of pairs involving a platoon vehicle (SUMO's own check is per
    lane) on roads that can touch (not a bridge over the other), and platoon vehicles
    crossing walls; each contact counts once, when it begins, with the vehicle at fault
    (`platoon_sumo.fault`)."""

    def __init__(self) -> None:
        self._contacts: Onset[tuple[str, str]] = Onset()
        self._placed: dict[str, tuple[float, frozenset[str]]] = {}
        """Vehicles SUMO placed near the platoons (fault rule 0): when, and which
        vehicles they landed within reach of."""

    def __call__(self, ctx: StepContext) -> None:
        world, rects = ctx.world, ctx.footprints
        dt_s = _interval_s(ctx)
        self._note_placed(ctx, dt_s)
        subjects = np.array([world.index[m.id] for m in ctx.fleet if m.id in world.index])
        if not len(subjects):
            self._contacts.update(())
            return
        if not np.isfinite(rects).all():
            raise ValueError(f"a footprint is not finite at t={world.time_s:.2f} s")
        pairs = overlapping_pairs_kernel(rects, np.unique(subjects), 0.0)
        network = ctx.run.plan.network
        now = {
            (a, b) if a < b else (b, a)
            for a, b in ((world.ids[i], world.ids[j]) for i, j in pairs)
            if network.same_level(world.lane_ids[world.index[a]], world.lane_ids[world.index[b]])
        }
        walls = ctx.run.static_segments
        if walls is not None:
            hits = rectangles_crossing_segments(rects[subjects], walls)
            now |= {(world.ids[subjects[i]], WALL) for i in np.unique(hits[:, 0])}
        for a, b in self._contacts.update(now):
            if b == WALL:  # walls do not move: the vehicle ran into it
                ctx.emit(EventKind.WALL_CONTACT, ctx.fleet.get(a) or a, other=WALL, at_fault=a)
                continue
            if ctx.fleet.get(a) is None:
                a, b = b, a  # the platoon vehicle first
            i, j = world.index[a], world.index[b]
            lanes = [_lane_yaw(network, world.lane_ids[k], rects[k]) for k in (i, j)]
            across = [
                None if lane is None else _across_mps(ctx, network, k, dt_s)
                for lane, k in zip(lanes, (i, j), strict=True)
            ]
            fault = contact_fault(
                rects[i], rects[j], world.speed_mps[i], world.speed_mps[j], lanes[0], lanes[1],
                _motion(ctx, i, dt_s), _motion(ctx, j, dt_s), dt_s or ctx.dt_s,
                _turn_rad(ctx, i), _turn_rad(ctx, j), self._placed_near(a, b, world.time_s),
                self._placed_near(b, a, world.time_s), across[0], across[1],
            )  # fmt: skip
            ctx.emit(
                EventKind.COLLISION, ctx.fleet.get(a) or a, other=b, detail=fault.reason,
                at_fault=(a, b)[fault.at_fault] if fault.at_fault is not None else "",
            )  # fmt: skip

    def _note_placed(self, ctx: StepContext, dt_s: float | None) -> None:
        """Remember which vehicles in both worlds SUMO placed over this step, and within
        whose reach they landed (what that vehicle covers in `PLACED_REACTION_S` at its
        speed, plus half the two lengths, centre to centre); forget older placements."""
        now_s = ctx.world.time_s
        for vid, (at_s, _) in list(self._placed.items()):
            if not _within_reaction(at_s, now_s):
                del self._placed[vid]
        before, rects_before = ctx.sensed_world, ctx.sensed_footprints
        if dt_s is None or before is None or rects_before is None:
            return
        world, rects = ctx.world, ctx.footprints
        was = before.index.get
        was_at = np.fromiter((was(vid, -1) for vid in world.ids), np.int64, len(world.ids))
        now_rows = np.flatnonzero(was_at >= 0)
        if not len(now_rows):
            return
        was_rows = was_at[now_rows]
        # how far the body moved: its farthest corner (a rigid body: at least its centre).
        # SUMO turned a car on the race circuit by 50 degrees in a step, its centre 0.96 m
        # beyond its speed, a corner 4 m: its side swept into a platoon car's corridor,
        # which touched it in the next step (seed 44, 102.9 s)
        corners = rectangle_corners(np.concatenate([rects[now_rows], rects_before[was_rows]]))
        moved = corners[: len(now_rows)] - corners[len(now_rows) :]
        moved_m = np.hypot(moved[..., 0], moved[..., 1]).max(axis=1)
        placed = was_placed(moved_m, world.speed_mps[now_rows], dt_s)
        reach = np.abs(world.speed_mps) * PLACED_REACTION_S + 0.5 * rects[:, LENGTH]
        for k in now_rows[placed]:
            apart = np.hypot(rects[:, CX] - rects[k, CX], rects[:, CY] - rects[k, CY])
            near = np.flatnonzero(apart <= reach + 0.5 * rects[k, LENGTH])
            self._placed[world.ids[k]] = (now_s, frozenset(world.ids[n] for n in near if n != k))

    def _placed_near(self, vehicle_id: str, other_id: str, now_s: float) -> bool:
        """Did SUMO place `vehicle_id` within `other_id`'s reach at most a reaction time
        before now (rule 0 of the fault)?"""
        placed = self._placed.get(vehicle_id)
        return placed is not None and _within_reaction(placed[0], now_s) and other_id in placed[1]


def _within_reaction(at_s: float, now_s: float) -> bool:
    """Is `at_s` at most `PLACED_REACTION_S` before `now_s` (SUMO's times, to rounding)?"""
    return now_s - at_s <= PLACED_REACTION_S + 1e-9


def _lane_yaw(network: Network, lane_id: str, rect: FloatArray) -> float | None:
    """The direction of the lane a vehicle drives along where its body is, for the
    sideways rule; None on an internal lane, and while part of the body is still
    behind the lane's start, as SUMO counts it (the front less than a vehicle length
    into the lane): turning out of a junction, the heading is the turn's, up to 140
    degrees off the lane entered on netconvert's invented ramps."""
    if not lane_id or lane_id.startswith(":"):
        return None
    front_x, front_y = centre_to_front_bumper(rect[CX], rect[CY], rect[YAW], rect[LENGTH])
    front = network.lane_frame(lane_id, float(front_x), float(front_y))
    if front is None or front[1] < rect[LENGTH]:
        return None
    centre = network.lane_frame(lane_id, rect[CX], rect[CY])
    return None if centre is None else centre[0]


def _interval_s(ctx: StepContext) -> float | None:
    """The time between the world the step began with and the new one [s] (None: no
    earlier world to compare with)."""
    before = ctx.sensed_world
    if before is None or ctx.sensed_footprints is None or ctx.world.time_s <= before.time_s:
        return None
    return ctx.world.time_s - before.time_s


def _before(ctx: StepContext, k: int) -> FloatArray | None:
    """Row `k`'s footprint in the world the step began with (None for a vehicle not in
    it: just departed, or outside the platoons' reach)."""
    before, rects_before = ctx.sensed_world, ctx.sensed_footprints
    if before is None or rects_before is None:
        return None
    was = before.index.get(ctx.world.ids[k])
    return None if was is None else rects_before[was]


def _motion(ctx: StepContext, k: int, dt_s: float | None) -> tuple[float, float] | None:
    """How row `k`'s footprint centre moved over the step [m/s] (x, y)."""
    was = _before(ctx, k)
    if was is None or dt_s is None:
        return None
    now = ctx.footprints[k]
    return (float(now[CX] - was[CX]) / dt_s, float(now[CY] - was[CY]) / dt_s)


def _across_mps(ctx: StepContext, network: Network, k: int, dt_s: float | None) -> float | None:
    """How fast row `k`'s front bumper moved across its lane over the step [m/s] (left
    +): the change of its distance to the lane's centre line, as SUMO's lateral
    position (None when not known)."""
    was = _before(ctx, k)
    if was is None or dt_s is None:
        return None
    offsets = []
    for rect in (was, ctx.footprints[k]):
        x, y = centre_to_front_bumper(rect[CX], rect[CY], rect[YAW], rect[LENGTH])
        frame = network.lane_frame(ctx.world.lane_ids[k], float(x), float(y))
        if frame is None:
            return None
        offsets.append(frame[2])
    return (offsets[1] - offsets[0]) / dt_s


def _turn_rad(ctx: StepContext, k: int) -> float:
    """How far row `k`'s footprint turned over the step [rad] (0 when not known)."""
    was = _before(ctx, k)
    return 0.0 if was is None else float(wrap_angle(ctx.footprints[k][YAW] - was[YAW]))
