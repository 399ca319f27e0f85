"""Obstacles ahead: for each member, the nearest vehicle whose footprint reaches into
the corridor the member is about to drive through. SUMO's leader only covers the route's
lanes; a car waiting inside a junction with its corner in the member's lane, or a car
crossing its path, is on other lanes. Ground truth, for the supervisor's last-resort
brake and the route-following controller (as SUMO's leader is)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.geometry import rectangle_corners
from platoon_sumo.kernels.corridor import MEMBER_COLUMNS, corridor_intrusions, empty_outputs
from platoon_sumo.kernels.lanes import lane_position, moved_along_lanes
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import LATERAL, ROUTE_S, SPEED, Member
from platoon_sumo.loop.paths import PathStack
from platoon_sumo.loop.progress import at_light, link_ahead
from platoon_sumo.path import RoutePath
from platoon_sumo.sumo.network import Network
from platoon_sumo.world import VehicleAhead, WorldSnapshot

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: The corridor is the vehicle's width plus this on each side [m].
CORRIDOR_MARGIN_M = 0.2
#: Longest slice of the corridor [m] (shorter for narrow vehicles: half their corridor).
SLICE_M = 0.5
#: A crossing vehicle is assumed able to brake this hard [m/s²] (SUMO's default
#: deceleration of passenger cars).
CROSSING_DECEL_MPS2 = 4.5
#: The corridor is a comfortable stop from the current speed (the supervisor's
#: `comfort_decel_mps2`) long, plus this many seconds of driving and this many metres.
LOOK_TIME_S, LOOK_EXTRA_M = 2.0, 10.0
#: A car slower than this [m/s] reaching into a member's corridor from one side, with
#: either of them inside a junction, is passed by a sidestep when the lane has room
#: (`sidestep_clearing`).
STANDING_MPS = 0.3
#: A car moving inside a junction is also seen where it will be over this long from
#: now [s], at these fractions of it, keeping the deceleration it showed over the last
#: step (or its speed).
AHEAD_S, AHEAD_FRACTIONS = 1.0, (0.25, 0.5, 0.75, 1.0)
#: Such cars are looked at within a corridor's length plus this of a member [m]: more
#: than a junction lane and a car.
JUNCTION_REACH_M = 50.0
#: Two cars side by side on one lane keep at least this much between them [m] (SUMO's
#: default `minGapLat`).
SIDE_BY_SIDE_M = 0.6
#: The sidestep clears the corridor by this much [m] and keeps the body this far
#: inside the lane's edges [m]; the outline is sampled every `OUTLINE_STEP_M`.
SIDESTEP_EXTRA_M, LANE_EDGE_CLEARANCE_M, OUTLINE_STEP_M = 0.05, 0.1, 0.25


class ObstaclesAhead:
    """Each member's `obstacle_ahead`: its route path from the front bumper on, shifted
    by its current lateral offset, `CORRIDOR_MARGIN_M` wider than the vehicle on each
    side, a comfortable stop plus `LOOK_TIME_S` of driving plus `LOOK_EXTRA_M` long; the
    nearest other footprint (on a road that can touch) reaching into it, with its speed
    along the corridor (0 when oncoming), unless it is crossing and will have left
    (`crosses_before_arrival`). SUMO's leader on the route lanes is not repeated here
    unless SUMO drives the member and the leader's body reaches into the corridor
    nearer than SUMO's gap says. A car SUMO is to move across the member's lane
    (`Backend.sideways_waits`) is an obstacle the member's SUMO minGap nearer than its
    back (along the lanes), standing, for a member that can stop there comfortably
    when it first sees it (and then until it has moved over); one that cannot, or is
    within that room already, drives on and the car moves over behind it
    (fokr_bs_demo, seed 42: a follower held 1.9 m behind a member standing on the next
    lane to move in front of it, which SUMO held for want of that room). A car moving
    inside a junction is also where it will be in `AHEAD_S` (`moving_footprints`): on
    DRT a car turning left across the other direction stopped with its corner in a
    follower's path, which saw it 3.7 m ahead at 11 m/s (seed 42, 341.0 s); another
    started across and stopped 5 m ahead of one at 9 m/s (seed 43, 264.7 s).
    One compiled pass over all members; the route paths are stacked once (a new route
    adds its path)."""

    def __init__(self) -> None:
        self._outputs = empty_outputs(64)
        self._rows: dict[tuple[int, str], tuple[float, float, float, float, float, float]] = {}
        self._paths = PathStack()
        self._lanes: JunctionLanes | None = None
        self._holding: dict[str, str] = {}
        """Members held behind a car SUMO is to move sideways, and that car."""
        self._yielding: dict[str, str] = {}
        """Members waiting for a car beside them to enter a junction, and that car."""

    def _constants(self, m: Member) -> tuple[float, float, float, float, float, float]:
        """(path index, 1 / (2 comfortable deceleration), spacing, stride, half width,
        body length) of a member's corridor: the same for every member of a platoon on
        one path."""
        key = (id(m.path), m.platoon_id)
        row = self._rows.get(key)
        if row is None:
            path, config = m.path, m.platoon.config
            index = self._paths.number(path)
            hw = 0.5 * config.vehicle.width_m + CORRIDOR_MARGIN_M
            stride = max(1, int(min(SLICE_M, hw) / path.spacing_m))
            brake = 1.0 / (2.0 * config.supervisor.comfort_decel_mps2)
            length = config.vehicle.length_m
            row = self._rows[key] = (index, brake, path.spacing_m, stride, hw, length)
        return row

    def _constants_of(self, members: Sequence[Member]) -> FloatArray:
        """`_constants` of each member, a row each (read-only: kept while the same
        members drive)."""
        table = np.array([self._constants(m) for m in members]).reshape(len(members), 6)
        table.flags.writeable = False
        return table

    def __call__(self, ctx: StepContext) -> None:
        world = ctx.world
        for m in ctx.fleet:
            m.obstacle_ahead = None
            m.sidestep_m = 0.0
        members: Sequence[Member] = ctx.fleet.members()
        if not all(m.id in world.index for m in members):
            members = [m for m in members if m.id in world.index]
        if not members or len(world.ids) < 2:
            return
        self._intrusions(ctx, members)
        ids, leaders = [m.id for m in members], [m.vehicle_ahead for m in members]
        for k, leader in enumerate(leaders):  # only one inside a junction may be a misfit
            at = world.index.get(leader.vehicle_id, -1) if leader is not None else -1
            if at < 0 or not world.lane_ids[at].startswith(":"):
                leaders[k] = None
        waits = ctx.backend.sideways_waits(ids, leaders)
        held, self._holding = self._holding, {}
        if not waits:
            return
        speeds = ctx.fleet.kin[ctx.fleet.rows(members), SPEED].tolist()
        for m, speed in zip(members, speeds, strict=True):
            wait = waits.get(m.id)
            if wait is None:
                continue
            other, gap = wait
            # SUMO's minGap is the room it asks for behind a car moving over at rest;
            # a member that cannot stop short of it comfortably when it first sees the
            # car drives on, as one already within it: the car moves over behind it
            room = gap - m.platoon.config.vehicle.min_gap_m
            stop = max(speed, 0.0) ** 2 * self._constants(m)[1]  # the corridor's stop
            if room < 0.0 or (held.get(m.id) != other and room < stop):
                continue
            self._holding[m.id] = other
            if m.obstacle_ahead is None or room < m.obstacle_ahead.gap_m:
                m.obstacle_ahead = VehicleAhead(other, room, 0.0)

    def _intrusions(self, ctx: StepContext, members: Sequence[Member]) -> None:
        world, rects = ctx.world, ctx.footprints
        table = np.empty((len(members), len(MEMBER_COLUMNS)))
        rows = ctx.fleet.rows(members)
        table[:, 1] = ctx.fleet.kin[rows, ROUTE_S]
        table[:, 2] = ctx.fleet.kin[rows, LATERAL]
        speed = np.maximum(ctx.fleet.kin[rows, SPEED], 0.0)
        constants = (
            ctx.fleet.fixed((self, "corridors"), self._constants_of)
            if members is ctx.fleet.members()
            else self._constants_of(members)
        )
        table[:, 0] = constants[:, 0]
        comfort_stop = speed * speed * constants[:, 1]
        table[:, 3] = comfort_stop + LOOK_TIME_S * speed + LOOK_EXTRA_M
        table[:, 4:] = constants[:, 2:]
        points, starts = self._paths.stacked("xy", lambda p: p.xy_m)
        normals, _ = self._paths.stacked("left normals", lambda p: p.left_normals)
        selves = np.array([world.index[m.id] for m in members], dtype=np.int64)
        network = ctx.run.plan.network
        fronts = np.column_stack([world.front_x_m[selves], world.front_y_m[selves]])
        reach = float(table[:, 3].max()) + JUNCTION_REACH_M
        if self._lanes is None:
            self._lanes = JunctionLanes(network)
        ahead, whose, standing = moving_footprints(
            world, ctx.sensed_world, self._lanes, fronts, reach
        )
        cars, lane_rows, beside, stops = self._entering(ctx, members, table, comfort_stop)
        entering, entrants, entrant_stands = entering_footprints(
            world, ctx.sensed_world, self._lanes, cars, lane_rows
        )
        seen_by = np.concatenate([np.full(len(rects) + len(ahead), -1), beside[entrants]])
        stop_at = np.concatenate([np.full(len(rects) + len(ahead), np.inf), stops[entrants]])
        owners = np.concatenate([np.arange(len(rects)), whose, cars[entrants]])
        every = np.concatenate([rects, ahead, entering])
        standing = np.concatenate([standing, entrant_stands])
        args = (points, normals, starts, table, selves, np.ascontiguousarray(every), owners)
        count = corridor_intrusions(*args, *self._outputs)
        if count > len(self._outputs[0]):
            self._outputs = empty_outputs(2 * count)
            count = corridor_intrusions(*args, *self._outputs)
        if not count:
            return
        who, rect, gap, along = (a[:count] for a in self._outputs)
        entry = seen_by[rect] == who  # waited for at the line, or before it (`_entering`)
        gap = np.where(entry, np.minimum(gap, stop_at[rect]), gap)
        owner = owners[rect]
        later = rect - len(rects)  # >= 0: where a moving car will be
        # a car entering the junction beside another member is not this member's
        skip = (seen_by[rect] != -1) & (seen_by[rect] != who)
        # SUMO's leader, whose gap along the lanes is the exact one, is followed at its
        # gap and speed (also where it will be); unless SUMO drives the member (its
        # safe speed keeps that gap) and the leader's body reaches nearer than the gap
        # by more than a slice of the corridor (a car standing across the lane:
        # osm_spreewaldring, SUMO's gap 4.41 m, the footprints 3.84 m apart, and the
        # follower ran into it). Members we place (planar) are left to SUMO's gap: the
        # nearer-body test gave the paper world's robots 449 emergency brakings in a
        # lap, none without it
        leader_row, leader_gap, sumo_drives = self._leaders(world, members)
        slice_m = constants[:, 3] * constants[:, 2]
        skip |= (owner == leader_row[who]) & (
            (later >= 0) | ~sumo_drives[who] | (gap > leader_gap[who] - slice_m[who])
        )
        kept = np.flatnonzero(~skip)
        order = kept[np.lexsort((rect[kept], gap[kept], who[kept]))]  # per member, nearest first
        j_of, i_of, ahead_at = who[order], owner[order], later[order]
        will_stop = entry[order]
        if len(standing):
            will_stop = will_stop | ((ahead_at >= 0) & standing[np.maximum(ahead_at, 0)])
        cos, other_speed = along[order], world.speed_mps[i_of]
        passes = will_stop | ~crosses_before_arrival(
            gap[order], speed[j_of], 2.0 * constants[j_of, 4], other_speed, cos,
            world.length_m[i_of], world.width_m[i_of],
        )  # fmt: skip
        speed_along = np.where(will_stop, 0.0, np.maximum(other_speed * cos, 0.0))
        picks = np.flatnonzero(passes)
        lane_ids, found = world.lane_ids, [False] * len(members)
        for j, i, g, v in zip(
            j_of[picks].tolist(), i_of[picks].tolist(), gap[order][picks].tolist(),
            speed_along[picks].tolist(), strict=True,
        ):  # fmt: skip
            if found[j]:
                continue
            own_lane, other_lane = lane_ids[selves[j]], lane_ids[i]
            # a bridge over the path is no obstacle. Compared with the member's own lane,
            # so a body beyond the next junction is not seen until the member reaches the
            # edge before it; compared with the route's lane at the hit instead, platoon
            # cars on osm_spreewaldring's invented on-ramp were held for good (8 of 12
            # arrived, not 12): open
            if not network.same_level(own_lane, other_lane):
                continue
            found[j] = True
            m = members[j]
            m.obstacle_ahead = VehicleAhead(world.ids[i], g, v)
            inside = own_lane.startswith(":") or other_lane.startswith(":")
            if world.speed_mps[i] < STANDING_MPS and inside:
                m.sidestep_m = sidestep_clearing(
                    m.path, float(table[j, 1]), float(table[j, 2]), float(table[j, 3]),
                    float(constants[j, 4]), 0.5 * m.platoon.config.vehicle.width_m, rects[i],
                )  # fmt: skip

    @staticmethod
    def _leaders(
        world: WorldSnapshot, members: Sequence[Member]
    ) -> tuple[IntArray, FloatArray, NDArray[np.bool_]]:
        """Per member: its SUMO leader's row in `world` (-2: none, or not in it), the
        leader's gap [m], and whether SUMO drives the member."""
        leaders = [m.vehicle_ahead for m in members]
        index = world.index
        rows = np.array(
            [-2 if a is None else index.get(a.vehicle_id, -2) for a in leaders], dtype=np.int64
        )
        gaps = np.array([math.inf if a is None else a.gap_m for a in leaders], dtype=np.float64)
        drives = np.array([m.actuator.sumo_drives for m in members], dtype=bool)
        return rows, gaps, drives

    def _entering(
        self, ctx: StepContext, members: Sequence[Member], table: FloatArray, stop_m: FloatArray
    ) -> tuple[IntArray, IntArray, IntArray, FloatArray]:
        """The cars about to enter a junction from a member's lane beside it
        (`entering_footprints`): world rows, lane rows (the lane leading to the junction
        lane each enters), the member (index in `members`) each is beside, and where
        that member stops for it [m ahead] (`entry_stop_m`). `table` is the members'
        corridors, `stop_m` their comfortable stopping distances.

        SUMO orders the cars on different approaches by the junction's right of way,
        but not two cars side by side on one wide lane (sublane model) that go on into
        the same narrow junction lane, or cross each other's paths in it. Race circuit,
        seed 44: a car on a 5 m lane 3.9 m right of its centre and a platoon car 0.5 m
        right of it entered a 3.2 m junction lane together; the platoon car stood in
        it behind the other, which waited at the junction's exit to move over into the
        side road, with the platoon car within the room it needed (a gridlock to the
        end). A moving car on the member's lane beside it (level with some of its body;
        a member only when its front is ahead: one of two goes first), that will be past
        the lane's end within `AHEAD_S` is seen there, on the junction lane it enters;
        the member waits for it (at the line at the latest), unless both go on into one
        junction lane wide enough for the two side by side (`SIDE_BY_SIDE_M` between
        them). A car wholly ahead is seen where it is. Into one lane, the member stops
        where it leaves its minGap behind the car's back once the car stands at the
        junction lane's end (SUMO holds a car there that must move over into the next
        lane); where that place is behind it, waiting would block that move, and the
        member goes first (a 3 m junction lane in `test_side_by_side_entry.py`); so does
        a member that cannot stop comfortably where it would wait when it first sees the
        car."""
        world, backend = ctx.world, ctx.backend
        assert self._lanes is not None
        members_ids: set[str] = set()
        occupants: dict[str, list[tuple[str, float, float, float]]] = {}
        on_lane: dict[str, list[int]] = {}
        found: list[tuple[int, int, int, float]] = []
        held, self._yielding = self._yielding, {}
        # members near their lane's end: (index, member, world row, lane, to its end [m])
        near_end = []
        for j, (m, corridor_m) in enumerate(zip(members, table[:, 3].tolist(), strict=True)):
            end_m = m.link_distance_m
            if end_m is None or end_m > corridor_m:
                continue
            me = world.index[m.id]
            lane = world.lane_ids[me]
            if lane and lane[0] != ":":
                near_end.append((j, m, me, lane, end_m))
        xs: list[float] = []
        ys: list[float] = []
        lengths: list[float] = []
        if near_end:  # the moving cars on those members' lanes
            members_ids = {m.id for m in ctx.fleet}
            wanted = {lane for *_, lane, _ in near_end}
            for i in np.flatnonzero(world.speed_mps >= STANDING_MPS).tolist():
                if world.lane_ids[i] in wanted:
                    on_lane.setdefault(world.lane_ids[i], []).append(i)
            # as Python floats: the test below runs for every pair, and math on numpy
            # scalars costs several times as much
            xs, ys = world.front_x_m.tolist(), world.front_y_m.tolist()
            lengths = world.length_m.tolist()
        for j, m, me, lane, end_m in near_end:
            # a car beside has its front within a car's length along the lane, so
            # within that and the lane's width in the plane: SUMO is asked only then
            reach = backend.lane_width(lane) + m.platoon.config.vehicle.length_m
            if not any(
                i != me and math.hypot(xs[i] - xs[me], ys[i] - ys[me]) <= reach + lengths[i]
                for i in on_lane.get(lane, ())
            ):
                continue
            # SUMO's link query only now, and not at a light: is there one?
            if not at_light(m, end_m) and link_ahead(ctx, m) is None:
                continue
            if lane not in occupants:
                occupants[lane] = backend.lane_occupants(lane)
            mine = next((o[1] for o in occupants[lane] if o[0] == m.id), None)
            if mine is None:
                continue
            back = mine - m.platoon.config.vehicle.length_m
            mine_next: str | None = None
            for other, front, speed, length in occupants[lane]:
                to_end = end_m - (front - mine)
                if (
                    other == m.id
                    or speed < STANDING_MPS
                    or front <= (mine if other in members_ids else back)
                    or front - length >= mine  # wholly ahead: in line, seen where it is
                    or not 0.0 <= to_end < speed * AHEAD_S
                    or other not in world.index
                ):
                    continue
                after = backend.next_junction_lane(other)
                if not after:
                    continue
                if mine_next is None:
                    mine_next = backend.next_junction_lane(m.id)
                i = world.index[other]
                both = m.platoon.config.vehicle.width_m + world.width_m[i] + SIDE_BY_SIDE_M
                if after == mine_next and backend.lane_width(after) >= both:
                    continue  # room for both side by side
                row = self._lanes.index(lane, after)
                if row < 0 or self._lanes.successor(row) < 0:
                    continue
                stop = entry_stop_m(
                    end_m, self._lanes.length_to_exit(self._lanes.successor(row)),
                    length, m.platoon.config.vehicle.min_gap_m, after == mine_next,
                )  # fmt: skip
                if stop is None:
                    continue
                # held only if it can stop there comfortably when it first sees the car
                # (then until the car is in); one too fast for that goes first
                if held.get(m.id) != other and stop_m[j] > stop:
                    continue
                self._yielding[m.id] = other
                found.append((i, row, j, stop))
        if not found:
            empty = np.empty(0, dtype=np.int64)
            return empty, empty, empty, np.empty(0)
        cars, rows, beside, stops = zip(*found, strict=True)
        return (
            np.array(cars, dtype=np.int64), np.array(rows, dtype=np.int64),
            np.array(beside, dtype=np.int64), np.array(stops),
        )  # fmt: skip


class JunctionLanes:
    """The shapes of the junction lanes cars were seen on, each with the lanes it leads
    to, stacked for `kernels.lanes` (a lane is added the first time a car is on it; the
    points go into a buffer that doubles when full)."""

    def __init__(self, network: Network) -> None:
        self._network = network
        self._index: dict[str, int] = {}
        self._points = np.empty((1024, 2))
        self._starts, self._lengths, self._successors = [0], list[float](), list[int]()
        self._internal: list[bool] = []
        self._stacked: tuple[FloatArray, IntArray, FloatArray, IntArray] | None = None

    def index(self, lane_id: str, then: str | None = None) -> int:
        """The lane's row (-1: unknown to the network or without a shape); leading to
        the junction lane it has (a junction's lane) or to `then` (a road's lane, with
        a row for each lane it leads to)."""
        key = lane_id if then is None else f"{lane_id} {then}"
        known = self._index.get(key)
        if known is not None:
            return known
        try:
            shape = self._network.lane_shape(lane_id)
        except (KeyError, ValueError):  # sumolib's answers to an unknown lane id
            shape = np.empty((0, 2))
        if len(shape) < 2:
            self._index[key] = -1
            return -1
        k = self._index[key] = len(self._lengths)
        start, end = self._starts[-1], self._starts[-1] + len(shape)
        while end > len(self._points):
            self._points = np.concatenate([self._points, np.empty_like(self._points)])
        self._points[start:end] = shape
        self._starts.append(end)
        steps = np.maximum((np.diff(shape, axis=0) ** 2).sum(axis=1), 1e-12)
        self._lengths.append(float(np.sqrt(steps).sum()))  # as the kernel walks it
        self._successors.append(-1)
        self._internal.append(lane_id.startswith(":"))
        self._stacked = None
        after = self._network.junction_successor(lane_id) if then is None else then
        if after:
            self._successors[k] = self.index(after)
        return k

    def successor(self, row: int) -> int:
        """The row of the lane a row's lane leads to (-1: none)."""
        return self._successors[row]

    def length_to_exit(self, row: int) -> float:
        """Along a junction lane's shape and the junction lanes it leads to, to the
        road [m]."""
        total = 0.0
        while row >= 0 and self._internal[row]:
            total += self._lengths[row]
            row = self._successors[row]
        return total

    def stacked(self) -> tuple[FloatArray, IntArray, FloatArray, IntArray]:
        """(points, starts, lengths, successors) for `kernels.lanes`."""
        if self._stacked is None:
            self._stacked = (
                self._points[: self._starts[-1]],
                np.array(self._starts, dtype=np.int64),
                np.array(self._lengths),
                np.array(self._successors, dtype=np.int64),
            )
        return self._stacked


def moving_footprints(
    world: WorldSnapshot,
    before: WorldSnapshot | None,
    lanes: JunctionLanes,
    near_xy_m: FloatArray,
    reach_m: float,
) -> tuple[FloatArray, IntArray, NDArray[np.bool_]]:
    """Where the cars moving inside a junction within `reach_m` of a point of
    `near_xy_m` will be over the next `AHEAD_S`: each moved along its junction lanes
    (and the road they lead to) as far as it drives by each of `AHEAD_FRACTIONS` of
    that time, keeping the deceleration it showed over the last step (or its speed, if
    it did not slow down) up to where it stops (`kernels.lanes`). Returns the
    footprints (`len(AHEAD_FRACTIONS)` per car, nearest first), whose they are, and
    whether the car will stand there. A car that enters a member's path must be seen
    before it is there: a car at 11 m/s needs about 13 m to stop comfortably, and
    SUMO's drivers start into a junction and then brake late for the car they yield
    to; a car crossing at speed is in the path between now and a second from now.
    `before` is the world a step earlier (None: no braking known)."""
    none = (np.empty((0, 5)), np.empty(0, dtype=np.int64), np.empty(0, dtype=np.bool_))
    if not len(near_xy_m):
        return none
    moving = np.flatnonzero(world.speed_mps >= STANDING_MPS)
    inside = np.array([i for i in moving.tolist() if world.lane_ids[i][:1] == ":"], dtype=np.int64)
    if not len(inside):
        return none
    xy = np.column_stack([world.front_x_m[inside], world.front_y_m[inside]])
    gaps = np.hypot(*(xy[:, None, :] - near_xy_m[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    inside = inside[gaps <= reach_m]
    rows = np.array([lanes.index(world.lane_ids[i]) for i in inside.tolist()], dtype=np.int64)
    inside, rows = inside[rows >= 0], rows[rows >= 0]
    if not len(inside):
        return none
    ahead, stands = _advance(world, before, inside)
    return _bodies_ahead(world, lanes, inside, rows, ahead), *_owners(inside, stands)


def entering_footprints(
    world: WorldSnapshot,
    before: WorldSnapshot | None,
    lanes: JunctionLanes,
    cars: IntArray,
    rows: IntArray,
) -> tuple[FloatArray, IntArray, NDArray[np.bool_]]:
    """As `moving_footprints`, for cars still on a road's lane (on lane row `rows`,
    which leads to the junction lane each enters): only where they will be past the
    lane's end (along its shape, as they are moved), on the junction's lane. Before
    that they are where they are now, beside it or not. Returns the footprints, which
    of `cars` each is, and whether it will stand there."""
    if not len(cars):
        return np.empty((0, 5)), np.empty(0, dtype=np.int64), np.empty(0, dtype=np.bool_)
    ahead, stands = _advance(world, before, cars)
    rects = _bodies_ahead(world, lanes, cars, rows, ahead)
    which, standing = _owners(np.arange(len(cars)), stands)
    points, starts, lengths, _ = lanes.stacked()
    to_end = np.array([
        lengths[r] - lane_position(points, starts[r], starts[r + 1], world.front_x_m[i],
                                   world.front_y_m[i])
        for i, r in zip(cars.tolist(), rows.tolist(), strict=True)
    ])  # fmt: skip
    past = ahead.ravel() > np.repeat(to_end, len(AHEAD_FRACTIONS))
    return rects[past], which[past], standing[past]


def entry_stop_m(
    to_line_m: float, junction_m: float, other_length_m: float, min_gap_m: float, same: bool
) -> float | None:
    """Where [m ahead] a member waits for a car beside it entering a junction lane
    `junction_m` long (to the road it leads to), the member `to_line_m` before the line:
    at the line, or before it where it leaves `min_gap_m` behind the car's back once the
    car stands at the junction lane's end (SUMO holds a car there that must move over
    into the next lane) when both go on into that one lane (`same`). None where that
    place is behind the member: waiting there would block that move, the member goes
    first."""
    if not same:
        return to_line_m
    stop = to_line_m + junction_m - other_length_m - min_gap_m
    return None if stop < 0.0 else min(stop, to_line_m)


def _advance(
    world: WorldSnapshot, before: WorldSnapshot | None, cars: IntArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """How far each car drives by each of `AHEAD_FRACTIONS` of `AHEAD_S` (rows),
    keeping the deceleration it showed since `before` (or its speed), and whether it
    stands by then."""
    speed = world.speed_mps[cars]
    decel = np.zeros(len(cars))
    if before is not None and world.time_s > before.time_s:
        earlier = np.array(
            [before.index.get(world.ids[i], -1) for i in cars.tolist()], dtype=np.int64
        )
        seen = earlier >= 0
        was = before.speed_mps[earlier[seen]]
        decel[seen] = (was - speed[seen]) / (world.time_s - before.time_s)
    decel = np.maximum(decel, 0.0)[:, None]
    t = AHEAD_S * np.asarray(AHEAD_FRACTIONS)[None, :]
    v = speed[:, None]
    stands = v <= decel * t  # stopped by then
    ahead = np.where(stands, v * v / (2.0 * np.maximum(decel, 1e-9)), v * t - 0.5 * decel * t * t)
    return ahead, stands


def _bodies_ahead(
    world: WorldSnapshot, lanes: JunctionLanes, cars: IntArray, rows: IntArray, ahead: FloatArray
) -> FloatArray:
    """The bodies (rows of rectangles) of `cars` (world rows, on lane rows `rows`) moved
    along their lanes by `ahead` (a row per car), nearest first per car."""
    k = ahead.shape[1]
    every = np.repeat(cars, k)
    length = world.length_m[every]
    poses = moved_along_lanes(
        *lanes.stacked(), np.repeat(rows, k), world.front_x_m[every], world.front_y_m[every],
        ahead.ravel(), length,
    )  # fmt: skip
    return np.column_stack([poses, length, world.width_m[every]])


def _owners(cars: IntArray, stands: NDArray[np.bool_]) -> tuple[IntArray, NDArray[np.bool_]]:
    """Whose each row of `_bodies_ahead` is, and whether the car stands there."""
    return np.repeat(cars, stands.shape[1]), stands.ravel()


def crosses_before_arrival(
    gap_m: FloatArray | float,
    speed_mps: FloatArray | float,
    corridor_width_m: FloatArray | float,
    other_speed_mps: FloatArray | float,
    cos_heading: FloatArray | float,
    other_length_m: FloatArray | float,
    other_width_m: FloatArray | float,
) -> NDArray[np.bool_]:
    """Will a vehicle moving across the corridor have left it before this one gets
    there, even if it starts braking now? Its sideways speed must carry its whole body
    (as projected across the corridor) over the corridor's width before this vehicle
    covers the gap at its current speed, and its braking distance at
    `CROSSING_DECEL_MPS2` must be longer than that crossing. A car crossing a junction
    ahead at speed is not a reason to brake in the junction; one standing, slow (it may
    stop in the way) or driving along the corridor stays an obstacle. Elementwise over
    arrays (one answer per hit)."""
    cos = np.asarray(cos_heading, dtype=np.float64)
    sin = np.sqrt(np.maximum(1.0 - cos * cos, 0.0))
    sideways = other_speed_mps * sin
    moving = sideways > 0.0
    across = corridor_width_m + other_length_m * sin + other_width_m * np.abs(cos)
    stops_after = ~(sideways * sideways / (2.0 * CROSSING_DECEL_MPS2) < across)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        sooner = across / sideways < gap_m / np.maximum(speed_mps, 1e-3)
    return np.asarray(moving & stops_after & sooner)


def sidestep_clearing(
    path: RoutePath,
    s_m: float,
    offset_m: float,
    length_m: float,
    corridor_half_m: float,
    body_half_m: float,
    rect: FloatArray,
) -> float:
    """The sideways shift (left +) after which `rect` no longer reaches into the
    corridor (from the front bumper at arc length `s_m`, `length_m` long, `offset_m`
    beside the path, `corridor_half_m` each side); 0 when it reaches in from both sides
    or across the middle, or when the shifted body would leave its lane.

    SUMO lets a car wait inside a junction at a point its network puts there, and in
    networks whose internal lanes overlap (the unrepaired DRT district) its corner can
    stand a few centimetres in our car's way: it waits for our car, which waits for it.
    SUMO's own cars drive through such a corner; ours go round it, within the lane."""
    corners = rectangle_corners(rect[None, :])[0]
    points = []
    for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
        n = max(2, math.ceil(math.hypot(*(b - a)) / OUTLINE_STEP_M) + 1)
        points.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    outline = np.concatenate(points)
    s, d = path.project_sl_many(outline[:, 0], outline[:, 1], s_m)
    inside = (s >= s_m) & (s <= s_m + length_m) & (np.abs(d - offset_m) < corridor_half_m)
    if not inside.any():
        return 0.0
    d = d[inside]
    if (d > offset_m).all():
        target = float(d.min()) - corridor_half_m - SIDESTEP_EXTRA_M
    elif (d < offset_m).all():
        target = float(d.max()) + corridor_half_m + SIDESTEP_EXTRA_M
    else:
        return 0.0
    room = 0.5 * path.lane_width_near(s_m) - body_half_m - LANE_EDGE_CLEARANCE_M
    return target - offset_m if abs(target) <= room else 0.0
