"""Gap acceptance for the lane changes our controllers steer (planar and sublane).

Members that steer their route's lane changes themselves are not checked by SUMO (planar:
placed; sublane: SUMO executes their sideways moves as asked): this stage tells the
supervisor whether the target lane has room (`LaneChangeAhead.clear`) and, during the
move, the nearest vehicle ahead in it. Lane-actuated members get None: SUMO makes their
changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import Member
from platoon_sumo.loop.ports import LaneOccupant
from platoon_sumo.path import LaneChange, RoutePath
from platoon_sumo.world import LaneChangeAhead, VehicleAhead

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LaneChangeParams:
    """Car-scale gap acceptance (gaps in metres and seconds, as a driver judges them)."""

    look_ahead_min_m: float = 60.0
    """The gap is judged once the change begins within max(this, `look_ahead_time_s` x
    speed) + `look_ahead_lengths` own lengths."""
    look_ahead_time_s: float = 8.0
    look_ahead_lengths: float = 10.0
    instants: int = 5
    """The target lane is predicted at this many instants, from entering to completing."""
    min_pace_mps: float = 5.0
    """The move's duration is judged at least at this speed."""
    gap_behind_m: float = 3.0
    gap_behind_time_s: float = 1.2
    """A vehicle behind must stay `gap_behind_m` + this x its speed behind us."""
    gap_ahead_m: float = 3.0
    gap_ahead_time_s: float = 0.6
    """A vehicle ahead must stay `gap_ahead_m` + this x our pace ahead of us."""
    side_clearance_m: float = 0.3
    """Sideways clearance kept to a vehicle alongside on the target lane."""
    sample_step_m: float = 0.5
    """The route ahead is sampled at this spacing for the sideways check."""
    side_reach_min_m: float = 60.0
    side_reach_time_s: float = 4.0
    side_reach_decel_mps2: float = 2.5
    """The sideways check looks max(min, time x speed) + speed² / (2 x decel) ahead."""
    alongside_ahead_m: float = 60.0
    alongside_behind_m: float = 80.0
    """Occupants farther than this ahead of our front / behind our rear are ignored."""
    alongside_margin_m: float = 1.0
    """Bodies within this lengthwise margin count as alongside."""
    approach_gap_m: float = 3.0
    approach_time_s: float = 0.5
    ahead_margin_m: float = 2.0
    """A vehicle not alongside is near when within `approach_gap_m` + `approach_time_s` x
    its speed (plus closing over the time to cross) behind, or `ahead_margin_m` (plus
    closing) ahead."""
    line_margin_m: float = 0.1
    """Near vehicles: the move pauses before our body comes this close to the line."""


class LaneChangeGaps:
    def __init__(self, params: LaneChangeParams | None = None) -> None:
        self.params = params or LaneChangeParams()
        self._lanes: dict[str, tuple[FloatArray, float]] = {}

    def __call__(self, ctx: StepContext) -> None:
        for m in ctx.fleet:
            m.lane_change = self._ahead(ctx, m) if m.actuator.steers else None

    def _ahead(self, ctx: StepContext, m: Member) -> LaneChangeAhead | None:
        """Is the target lane of the next lane change free for the whole move?

        Each vehicle on the target lane(s) is moved forward at its own speed and compared
        with where we will be at `instants` instants of the move: it must stay a time gap
        of its own behind us or a gap of ours ahead."""
        p = self.params
        change = m.path.next_lane_change(m.route_s_m)
        if change is None:
            return None
        distance = change.begin_s_m - m.route_s_m
        speed = m.speed_mps
        length = m.platoon.config.vehicle.length_m
        reach = max(p.look_ahead_min_m, p.look_ahead_time_s * speed)
        if distance > reach + p.look_ahead_lengths * length:
            return None
        # The target lanes the member already drives in are no gap to wait for, nor to
        # pause a sideways move for (a steered car may be there before its path: it
        # followed its predecessor, or SUMO made the change for it). Counted, its own
        # follower right behind it in that lane held it, and the follower waited for
        # it: members of a platoon stood beside each other for good.
        here = ctx.world.lane_ids[ctx.world.index[m.id]] if m.id in ctx.world.index else ""
        targets = change.target_lane_ids
        if here in targets:
            targets = targets[targets.index(here) + 1 :]
        move_m = change.end_s_m - change.begin_s_m
        if distance <= 0.0:  # under way: the vehicle ahead in the target lane, and sideways
            on_lane = {lane: ctx.backend.lane_occupants(lane) for lane in change.target_lane_ids}
            occupants = [o for lane in change.target_lane_ids for o in on_lane[lane]]
            own = change.begin_lane_pos_m - distance
            ahead = [(pos - other_len - own, vid, spd) for vid, pos, spd, other_len in occupants
                     if vid != m.id and pos - other_len > own - 1e-9]  # fmt: skip
            leader = VehicleAhead(min(ahead)[1], min(ahead)[0], min(ahead)[2]) if ahead else None
            beside = [o for lane in targets for o in on_lane[lane]]
            hold = self._sideways_hold_m(ctx, m, change, beside)
            if hold is not None:
                return LaneChangeAhead(hold, clear=False, target_leader=leader)
            return LaneChangeAhead(distance, clear=True, target_leader=leader)
        occupants = [
            o for lane in targets for o in ctx.backend.lane_occupants(lane) if o[0] != m.id
        ]
        pace = max(speed, p.min_pace_mps)
        last = p.instants - 1
        for k in range(p.instants):
            along = k / last * move_m
            t = (distance + along) / pace
            own = change.begin_lane_pos_m + along
            for _, pos, other_speed, other_len in occupants:
                predicted = pos + other_speed * t
                behind = predicted < own - length - (
                    p.gap_behind_m + p.gap_behind_time_s * other_speed
                )
                ahead_ok = predicted - other_len > own + p.gap_ahead_m + p.gap_ahead_time_s * pace
                if not (behind or ahead_ok):
                    return LaneChangeAhead(distance, clear=False)
        hold = self._sideways_hold_m(ctx, m, change, occupants)
        if hold is not None:
            return LaneChangeAhead(min(hold, distance), clear=False)
        return LaneChangeAhead(distance, clear=True)

    def _sideways_hold_m(
        self, ctx: StepContext, m: Member, change: LaneChange, occupants: list[LaneOccupant]
    ) -> float | None:
        """Distance to where the sideways move must pause, or None to go on.

        The gap check before a lane change predicts the target lane at constant speeds,
        but a move over half a long edge takes many seconds. Worse, SUMO places a moved
        vehicle on the lane under its centre: while our body straddles the lane line, the
        drivers of the target lane do not see it (no shadow-lane registration for
        moveToXY), so they neither brake nor swerve. Hence, every step:

        - a vehicle on the target lane(s) *alongside*: the move pauses where our side
          would come within `side_clearance_m` of its side;
        - a vehicle *coming up from behind* or just ahead, close enough to reach us
          before our centre is over the line: the move pauses before our body touches
          the line; once the body is over the line the move goes on (stopping there
          would leave us invisible to that lane), SUMO sees us once the centre crosses.

        Braking stops the sideways motion too (a car's lateral progress needs forward
        progress). Measured across the occupant's lane, its lateral position included.
        """
        p = self.params
        world = ctx.world
        if not occupants:
            return None
        speed = m.speed_mps
        cfg = m.platoon.config.vehicle
        own_front = change.begin_lane_pos_m + (m.route_s_m - change.begin_s_m)
        own_rear = own_front - cfg.length_m
        start = max(m.route_s_m, change.begin_s_m)
        stop = change.end_s_m
        if stop <= start:
            return None
        reach = max(p.side_reach_min_m, p.side_reach_time_s * speed) + speed * speed / (
            2.0 * p.side_reach_decel_mps2
        )
        samples = np.arange(start, min(stop, start + reach) + p.sample_step_m, p.sample_step_m)
        points = _path_points(m.path, samples)
        lateral_on: dict[str, FloatArray] = {}
        hold: float | None = None
        for vid, pos, other_speed, other_len in occupants:
            i = world.index.get(vid)
            if (
                vid == m.id
                or i is None
                or pos > own_front + p.alongside_ahead_m
                or pos < own_rear - p.alongside_behind_m
            ):
                continue
            lane = world.lane_ids[i]
            if not lane or lane.startswith(":"):
                continue
            shape, half_lane = self._lane_geometry(ctx, lane)
            if lane not in lateral_on:
                lateral_on[lane] = _lateral_offsets(shape, points)
            lateral = lateral_on[lane]
            front = np.array([[world.front_x_m[i], world.front_y_m[i]]])
            other_lat = float(_lateral_offsets(shape, front)[0])
            body_gap = np.abs(lateral - other_lat) - 0.5 * (cfg.width_m + float(world.width_m[i]))
            line_gap = np.abs(lateral) - 0.5 * cfg.width_m - half_lane
            # time until our centre is over the occupant's lane line
            inside = np.nonzero(np.abs(lateral) < half_lane)[0]
            to_centre_m = samples[inside[0] if inside.size else -1] - m.route_s_m
            t_cross = to_centre_m / max(speed, 1.0)
            margin = p.alongside_margin_m
            alongside = pos - other_len < own_front + margin and pos > own_rear - margin
            if alongside:
                bad = np.nonzero(body_gap < p.side_clearance_m)[0]
            else:
                closing = other_speed - speed
                behind_m = (
                    p.approach_gap_m + p.approach_time_s * other_speed
                    + max(closing, 0.0) * t_cross
                )  # fmt: skip
                ahead_m = p.ahead_margin_m + max(-closing, 0.0) * t_cross
                near = pos - other_len < own_front + ahead_m and pos > own_rear - behind_m
                if not near or line_gap[0] < 0.0:
                    continue  # far, or already over the line: commit
                bad = np.nonzero(line_gap < p.line_margin_m)[0]
            if bad.size:
                at = float(samples[bad[0]]) - m.route_s_m
                hold = at if hold is None else min(hold, at)
        return hold

    def _lane_geometry(self, ctx: StepContext, lane_id: str) -> tuple[FloatArray, float]:
        """A lane's centre-line and half width (cached)."""
        found = self._lanes.get(lane_id)
        if found is None:
            found = (ctx.backend.lane_shape(lane_id), 0.5 * ctx.backend.lane_width(lane_id))
            self._lanes[lane_id] = found
        return found


def _lateral_offsets(shape: FloatArray, points: FloatArray) -> FloatArray:
    """Signed distance (left +) of each point from the nearest segment of a polyline."""
    a = shape[:-1]
    d = shape[1:] - a
    rel = points[:, None, :] - a[None, :, :]
    seg2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-18)
    t = np.clip(np.einsum("nij,ij->ni", rel, d) / seg2, 0.0, 1.0)
    closest = a[None, :, :] + t[:, :, None] * d[None, :, :]
    dist2 = ((points[:, None, :] - closest) ** 2).sum(axis=2)
    k = np.argmin(dist2, axis=1)
    n = np.arange(len(points))
    cross = d[k, 0] * rel[n, k, 1] - d[k, 1] * rel[n, k, 0]
    return np.asarray(np.copysign(np.sqrt(dist2[n, k]), cross), dtype=np.float64)


def _path_points(path: RoutePath, s_m: FloatArray) -> FloatArray:
    """Positions of a path at many arc lengths."""
    n = len(path.xy_m)
    i = np.clip((np.asarray(s_m) / path.spacing_m).astype(np.int64), 0, n - 2)
    d = path.xy_m[i + 1] - path.xy_m[i]
    t = np.clip((np.asarray(s_m) - i * path.spacing_m) / path.spacing_m, 0.0, 1.0)
    return np.asarray(path.xy_m[i] + d * t[:, None], dtype=np.float64)
