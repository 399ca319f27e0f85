"""Route progress: where each member is on its route, what SUMO sees ahead of it (next
light, leader, link), red-light violations, and removal at the route's end."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.control.base import reads_link_ahead
from platoon_sumo.events import EventKind
from platoon_sumo.kernels.route import project_members
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import LATERAL, ROUTE_S, Member
from platoon_sumo.loop.paths import PathStack
from platoon_sumo.loop.ports import FloatArray
from platoon_sumo.world import LinkAhead, SignalAhead

IntArray = NDArray[np.int64]

#: A member whose front bumper is this close to its path's end has arrived [m].
ARRIVAL_TOLERANCE_M = 0.05


def crossed_stop_line(
    previous: SignalAhead, current: SignalAhead | None, travelled_m: float
) -> bool:
    """Did the vehicle drive over `previous`'s stop line during the last step?

    The signal ahead also changes when a lane change puts another link of the same light
    ahead: only a line within the distance just travelled counts as passed."""
    same = current is not None and (current.tls_id, current.link_index) == (
        previous.tls_id,
        previous.link_index,
    )
    return not same and previous.distance_m <= travelled_m + 0.25


def ahead_horizon_m(m: Member, dt_s: float) -> float:
    """How far SUMO's leader and junction link are read: farther than any stop from
    top speed (the vehicle's own braking, twice, or the supervisor's comfortable
    braking to its stop margin) and at least 20 vehicle lengths."""
    vehicle, supervisor = m.platoon.config.vehicle, m.platoon.config.supervisor
    v = vehicle.max_speed_mps
    comfortable = v * v / (2 * supervisor.comfort_decel_mps2) + supervisor.stop_margin_m + v * dt_s
    return max(20.0 * vehicle.length_m, v * v / vehicle.max_decel_mps2 * 2, comfortable)


def link_ahead(ctx: StepContext, m: Member) -> LinkAhead | None:
    """`m`'s link at the end of its lane (within its horizon), read from SUMO when a
    stage first asks for it this step (`RouteProgress` leaves it unread where neither
    the supervisor nor the controller reads it). SUMO does not step before those
    stages, and the one call between (a standoff's right of way, which sets that car's
    speed mode) changes neither whether a car has a link nor where it is: the standoff
    rule reads a car's link before it acts on that car, the side-by-side rule only
    asks whether there is one."""
    if m.lane_end_m is not None:
        m.link_ahead, m.lane_end_m = ctx.backend.link_ahead(m.id, m.lane_end_m), None
    return m.link_ahead


def at_light(m: Member, lane_end_m: float) -> bool:
    """Whether the link at the end of `m`'s lane (`lane_end_m` ahead) is its next
    light's: SUMO's next light on the route lies exactly at the lane's end
    (`SumoBackend.route_contexts` measures both from the same lane position). There is
    then a link, and it shows the light's state, which the stages that would otherwise
    make SUMO's link query (about 25 µs) need to know."""
    return m.signal is not None and m.signal.distance_m == lane_end_m


class RouteProgress:
    def __init__(self) -> None:
        self._paths = PathStack()

    def __call__(self, ctx: StepContext) -> None:
        members = ctx.fleet.members()
        if not members:
            return
        fleet = ctx.fleet
        rows = fleet.rows(members)
        front_x_m, front_y_m = fleet.front_bumpers(rows)
        previous_s_m = fleet.kin[rows, ROUTE_S]
        ids, windows, horizons, read, path_of = fleet.fixed(
            (self, "route progress"), lambda ms: self._fixed(ms, ctx.dt_s)
        )
        unknown = np.flatnonzero(~np.isfinite(previous_s_m))
        if len(unknown):
            m = members[int(unknown[0])]
            raise ValueError(
                f"{m.id}'s arc length on its route is {previous_s_m[unknown[0]]} at "
                f"t={ctx.world.time_s:.2f} s: its state is not finite"
            )
        route_s, lateral = self._project(path_of, front_x_m, front_y_m, previous_s_m, windows)
        fleet.kin[rows, ROUTE_S] = route_s
        fleet.kin[rows, LATERAL] = lateral
        route_s_m = route_s.tolist()
        travelled = np.maximum(route_s - previous_s_m, 0.0).tolist()
        contexts = ctx.backend.route_contexts(ids, horizons, read)
        for m, s_m, travelled_m, (signal, ahead, link) in zip(
            members, route_s_m, travelled, contexts, strict=True
        ):
            previous, m.signal = m.signal, signal
            m.vehicle_ahead = ahead
            if link is None or isinstance(link, LinkAhead):
                m.link_ahead, m.lane_end_m = link, None
            else:  # not read: the distance to the lane's end
                m.link_ahead, m.lane_end_m = None, float(link)
            if (
                previous is not None
                and previous.state in ("r", "u")
                and crossed_stop_line(previous, signal, travelled_m)
            ):
                ctx.emit(
                    EventKind.RED_LIGHT, m, other=previous.tls_id,
                    detail=f"link {previous.link_index} {previous.state}",
                )  # fmt: skip
            if s_m >= m.path.length_m - ARRIVAL_TOLERANCE_M:
                ctx.remove(m, arrived=True)

    def _fixed(
        self, members: Sequence[Member], dt_s: float
    ) -> tuple[list[str], FloatArray, list[float], list[bool], IntArray]:
        """What stays the same while the same members drive: their ids, search windows,
        SUMO look-ahead horizons [m], whether their links are read now (for the members
        whose supervisor yields at junctions, those SUMO does not drive, or whose
        controller may read it; else on demand) and their paths' numbers."""
        windows = [max(10.0, 4.0 * m.platoon.config.vehicle.length_m) for m in members]
        read = [not m.actuator.sumo_drives or reads_link_ahead(type(m.controller)) for m in members]
        path_of = np.array([self._paths.number(m.path) for m in members], dtype=np.int64)
        return (
            [m.id for m in members], np.array(windows),
            [ahead_horizon_m(m, dt_s) for m in members], read, path_of,
        )  # fmt: skip

    def _project(
        self, path_of: IntArray, x_m: FloatArray, y_m: FloatArray, hint_s_m: FloatArray,
        window_m: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:  # fmt: skip
        """Each member's front bumper projected on its path (numbers `path_of`) near its
        last arc length (``RoutePath.project_sl``, bit for bit): (arc lengths, lateral
        offsets)."""
        stack = self._paths
        xy, xy_starts = stack.stacked("xy", lambda p: p.kernel_arrays[0])
        blocks, block_starts = stack.stacked("blocks", lambda p: p.kernel_arrays[1])
        widths, _ = stack.stacked("lane widths", lambda p: p.kernel_arrays[2])
        geometry, _ = stack.stacked("geometry", lambda p: p.kernel_arrays[5][None, :2])
        return project_members(
            xy, xy_starts, blocks, block_starts, widths, geometry, path_of, x_m, y_m,
            hint_s_m, window_m,
        )  # fmt: skip
