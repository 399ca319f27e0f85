"""The live view: what a run shows in sumo-gui (`platoon-sumo run --gui`).

A step hook that only draws: platoon vehicles coloured by platoon (the leader ringed),
the laser rays and hit points of the chosen vehicles as SUMO polygons, the chosen
vehicle's predecessor outlined, the view following the chosen vehicle. Shapes, colours
and the view do not enter SUMO's dynamics, so a run with the live view has the same
trajectories as one without (tests/integration/test_live_view.py). It talks TraCI to the
sumo-gui that `SumoBackend` started with `SumoOptions.gui`; nothing else uses it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.geometry import footprints_from_front_bumper, rectangle_corners
from platoon_sumo.loop.context import RunContext, RunOutcome, StepHook, StepRecord, VehicleRecord
from platoon_sumo.sensors.laser import LaserScan

#: One colour per platoon, in platoon-id order as in the report's map and the
#: animations (RGB; matplotlib's tab10).
PLATOON_COLOURS = (
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
    (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207),
)  # fmt: skip
RAY_COLOUR = (0, 200, 0, 140)
VIEW_COLOUR = (0, 200, 0, 70)
HIT_COLOUR = (230, 0, 0, 255)
PREDECESSOR_COLOUR = (255, 0, 255, 255)
#: At most this many rays of one scan are drawn (every k-th ray of a denser scan).
MAX_RAYS_DRAWN = 360
#: Neighbouring hits at most this far apart are drawn as one surface [m].
SURFACE_JOIN_M = 0.6
#: At most this many surfaces of one scan are drawn (one polygon each).
MAX_SURFACES_DRAWN = 60
#: Half the length of the tick drawn at a lone hit [m].
HIT_MARK_M = 0.15
#: Polygon layer above the road and the vehicles.
LAYER = 100
VIEW = "View #0"

RaysOf = Literal["chosen", "all", "none"]


@dataclass(frozen=True)
class LiveViewOptions:
    """What the live view shows: whose rays, which vehicle it follows and zooms on."""

    vehicle: str | None = None
    """The vehicle followed, whose rays and predecessor are drawn (default: the first
    platoon vehicle with a laser scan and a predecessor, else the first one)."""
    rays: RaysOf = "chosen"
    zoom: float = 600.0
    """sumo-gui's zoom on the followed vehicle [%]."""
    delay_ms: float = 0.0
    """Pause between steps [ms] (sumo-gui's delay; its toolbar changes it live)."""


class LiveView(StepHook):
    """Draws each step into sumo-gui (see the module docstring)."""

    def __init__(self, options: LiveViewOptions | None = None):
        import traci

        self._traci: Any = traci
        self.options = options or LiveViewOptions()
        self._colours: dict[str, tuple[int, int, int]] = {}
        self._painted: set[str] = set()
        self._shapes: set[str] = set()
        self._followed: str | None = None

    def on_start(self, run: RunContext) -> None:
        self._traci.gui.setSchema(VIEW, "real world")  # vehicles drawn with their shapes
        ids = sorted(platoon.config.id for platoon in run.plan.platoons)  # as the report's
        for k, platoon_id in enumerate(ids):
            self._colours[platoon_id] = PLATOON_COLOURS[k % len(PLATOON_COLOURS)]

    def on_step(self, record: StepRecord) -> None:
        vehicles = record.vehicles
        for v in vehicles:
            if v.id not in self._painted:
                self._paint(v)
        chosen = self._chosen(vehicles)
        if chosen is not None and chosen.id != self._followed:
            self._traci.gui.trackVehicle(VIEW, chosen.id)
            self._traci.gui.setZoom(VIEW, self.options.zoom)
            self._followed = chosen.id
        drawn: set[str] = set()
        for v in vehicles:
            scan = v.scan
            wanted = self.options.rays == "all" or (
                self.options.rays == "chosen" and chosen is not None and v.id == chosen.id
            )
            if wanted and scan is not None:
                drawn |= self._draw_scan(v.id, scan)
        if chosen is not None and chosen.predecessor_id is not None:
            outline = footprint(record, chosen.predecessor_id)
            if outline is not None:
                drawn.add(
                    self._polygon(f"predecessor:{chosen.id}", outline, PREDECESSOR_COLOUR, 0.3, 2)
                )
        for stale in self._shapes - drawn:  # a vehicle that left, or lost its predecessor
            self._traci.polygon.remove(stale)
        self._shapes = drawn

    def on_end(self, outcome: RunOutcome) -> None:
        pass

    def _paint(self, v: VehicleRecord) -> None:
        colour = self._colours.get(v.platoon_id, PLATOON_COLOURS[0])
        self._traci.vehicle.setColor(v.id, (*colour, 255))
        if v.member_index == 0:  # the leader: a ring of its platoon's colour that follows it
            self._traci.vehicle.highlight(v.id, (*colour, 255), 0.75 * v.length_m)
        self._painted.add(v.id)

    def _chosen(self, vehicles: tuple[VehicleRecord, ...]) -> VehicleRecord | None:
        """The vehicle asked for; else the followed one while it scans a predecessor,
        else the first that does, else the followed one or the first."""
        if self.options.vehicle is not None:
            return next((v for v in vehicles if v.id == self.options.vehicle), None)
        scanning = [v for v in vehicles if v.scan is not None and v.predecessor_id is not None]
        current = [v for v in vehicles if v.id == self._followed]
        for candidates in ([v for v in scanning if v.id == self._followed], scanning, current):
            if candidates:
                return candidates[0]
        return vehicles[0] if vehicles else None

    def _draw_scan(self, vehicle_id: str, scan: LaserScan) -> set[str]:
        rays, surfaces = scan_shapes(scan)
        names = {self._polygon(f"view:{vehicle_id}", field_of_view(scan), VIEW_COLOUR, 0.05)}
        if len(rays):
            names.add(self._polygon(f"rays:{vehicle_id}", rays, RAY_COLOUR, 0.05))
        for k, surface in enumerate(surfaces):
            names.add(self._polygon(f"hits:{vehicle_id}:{k}", surface, HIT_COLOUR, 0.3, 1))
        return names

    def _polygon(
        self,
        name: str,
        shape: NDArray[np.float64],
        colour: tuple[int, ...],
        width_m: float,
        above: int = 0,
    ) -> str:
        """Draw (or move) the polygon `name`; `above` lifts it over the other shapes."""
        points = [(float(x), float(y)) for x, y in shape]
        if name in self._shapes:
            self._traci.polygon.setShape(name, points)
        else:
            self._traci.polygon.add(
                name, points, colour, fill=False, layer=LAYER + above, lineWidth=width_m
            )
        return name


def scan_shapes(
    scan: LaserScan,
) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
    """What SUMO draws of a scan, as unfilled polygons: the rays that returned as one
    polyline (sensor -> hit -> sensor -> next hit ...), and the hit points as the
    surfaces they trace: a polyline through each run of neighbouring hits at most
    `SURFACE_JOIN_M` apart (a lone hit: a short tick across its ray)."""
    step = max(1, math.ceil(scan.ranges.size / MAX_RAYS_DRAWN))
    ranges = scan.ranges[::step]
    angles = scan.angle_min + scan.angle_increment * step * np.arange(ranges.size)
    hit = np.isfinite(ranges) & (ranges > 0.0)
    r, a = ranges[hit], angles[hit] + scan.heading_rad
    if r.size == 0:
        return np.empty((0, 2)), []
    ux, uy = np.cos(a), np.sin(a)
    ends = np.column_stack([scan.origin_x_m + r * ux, scan.origin_y_m + r * uy])
    origin = np.broadcast_to([scan.origin_x_m, scan.origin_y_m], ends.shape)
    rays = np.stack([origin, ends], axis=1).reshape(-1, 2)
    index = np.flatnonzero(hit)
    apart = np.hypot(*np.diff(ends, axis=0).T) > SURFACE_JOIN_M
    breaks = np.flatnonzero((np.diff(index) > 1) | apart) + 1
    across = np.column_stack([-uy, ux]) * HIT_MARK_M  # perpendicular to each ray
    surfaces = []
    for run, ticks in zip(np.split(ends, breaks), np.split(across, breaks), strict=True):
        surfaces.append(run if len(run) > 1 else np.vstack([run - ticks, run + ticks]))
    return rays, surfaces[:MAX_SURFACES_DRAWN]


def field_of_view(scan: LaserScan, points: int = 48) -> NDArray[np.float64]:
    """The outline of what the laser can see: sensor -> the arc at `range_max` -> sensor."""
    a = scan.heading_rad + np.linspace(scan.angle_min, scan.angle_max, points)
    arc = np.column_stack([np.cos(a), np.sin(a)]) * scan.range_max
    origin = np.array([[scan.origin_x_m, scan.origin_y_m]])
    return np.vstack([origin, origin + arc, origin])


def footprint(record: StepRecord, vehicle_id: str) -> NDArray[np.float64] | None:
    """The closed outline (5, 2) of a vehicle of the step's world, or None."""
    world = record.world
    i = world.index.get(vehicle_id)
    if i is None:
        return None
    rect = footprints_from_front_bumper(
        world.front_x_m[i], world.front_y_m[i], world.yaw_rad[i], world.length_m[i],
        world.width_m[i],
    )  # fmt: skip
    corners = rectangle_corners(rect)[0]
    return np.vstack([corners, corners[:1]])
