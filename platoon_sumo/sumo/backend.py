"""The only module that talks to SUMO (through libsumo, or TraCI to sumo-gui for the
live view: the same calls, so a run is the same either way).

State is read once per step, in batch, into numpy arrays; platoon vehicles are pushed
back with moveToXY + setPreviousSpeed (planar actuation) or get a speed through setSpeed
(lane actuation). Every libsumo failure becomes a SumoError that says what we were doing.
"""

from __future__ import annotations

import bisect
import contextlib
import functools
import itertools
import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import libsumo
import numpy as np
import sumo
from numpy.typing import NDArray

from platoon_sumo.errors import SumoError
from platoon_sumo.kernels.neighbours import lanes_within, within_radius
from platoon_sumo.world import STOP_STATES, LinkAhead, SignalAhead, VehicleAhead, WorldSnapshot

#: SUMO's laneChangeMode bits: strategic changes (1) respecting others' speed and braking
#: gaps (512) with sublane adjustments (1024); no cooperative, speed-gain or keep-right
#: changes (SUMO's default is 1621).
LANE_CHANGE_STRATEGIC_ONLY = 1 + 512 + 1024
#: Lane-change mode of sublane actuation: only our sideways requests, executed as asked
#: (our gap acceptance, `LaneChangeGaps`, judges the route's lane changes as for planar
#: cars; SUMO's own checks blocked platoon members moving sideways beside each other);
#: no change, lateral alignment or strategic move of SUMO's own.
LANE_CHANGE_REQUESTS_ONLY = 0
#: SUMO's speedMode bits: safe speed (1), maximum acceleration (2) and deceleration (4),
#: right of way at junctions (8), braking for red lights (16): SUMO's default, and the
#: same without yielding at junctions (it still keeps its distance to vehicles inside).
DEFAULT_SPEED_MODE, TAKING_RIGHT_OF_WAY = 31, 31 - 8
#: Junction foes are looked for this far ahead of a vehicle [m].
JUNCTION_FOES_M = 50.0
#: Sublane actuation: slower sideways commands are a stop of the lateral move [m/s].
MIN_LATERAL_SPEED_MPS = 0.005
#: Sublane actuation asks for a lateral offset at least this far (and v² m) beyond,
#: so that SUMO's stopping bound does not slow the move [m].
LATERAL_REACH_M = 1.0
#: Sublane actuation: a vehicle slower than this [m/s] on a lane its route leaves
#: within `LANE_END_REACH_M` (or on this edge, after `HAND_OVER_AFTER_S`) has its lane
#: change made by SUMO (our steering moves a car sideways only while it drives).
HAND_OVER_BELOW_MPS = 2.0
#: [m] see `HAND_OVER_BELOW_MPS`.
LANE_END_REACH_M = 30.0
#: Sublane actuation: a vehicle slow this long [s] on a lane its route leaves on this
#: edge has its lane change made by SUMO (held by our gap check before a queue).
HAND_OVER_AFTER_S = 10.0
#: Sublane actuation: a sideways move the route needs that is steeper than this [tan of
#: the angle off the lanes] and, at the car's speed, faster sideways than
#: `STEER_COMFORT_LATERAL_MPS` is SUMO's to make (`SumoBackend._too_steep`).
STEER_MAX_LANE_TAN = math.tan(math.radians(10.0))
#: [m/s] see `STEER_MAX_LANE_TAN` (SUMO's default `maxSpeedLat`).
STEER_COMFORT_LATERAL_MPS = 1.0
#: Lateral speed of SUMO's lane changes made for a slow sublane-actuated car [m/s]
#: (SUMO's default `maxSpeedLat`).
HANDED_OVER_LATERAL_MPS = 1.0
#: A car whose lane change SUMO made is steered by us again within this distance of
#: its new lane's centre [m].
HANDED_BACK_WITHIN_M = 0.3
#: SUMO's lane-change state bits: the car wants to change left, right (`getLaneChangeState`).
LCA_LEFT, LCA_RIGHT = 2, 4
#: A car inside a junction this much [m] farther from its lane's centre than its body
#: fits the lanes after it has to be moved sideways before it may leave
#: (`SumoBackend.sideways_waits`).
MISFIT_TOLERANCE_M = 0.1
#: Sublane actuation: a lane change that SUMO, keeping the lane position, puts down
#: farther than this from where the car drives to [m] is a jump
#: (`SumoBackend.lane_change_landings`), as is a move this long at a bend of a lane's
#: shape (`SumoBackend.bends_ahead`).
LANDING_SHIFT_M = 0.3
#: Sublane actuation: so many sharp bends of its lane ahead of a car are fitted for, and
#: vertices of a lane's shape this close together [m] are one bend
#: (`SumoBackend.bends_ahead`).
BENDS_AHEAD, BEND_MERGE_M = 3, 2.0
#: A vehicle standing this close behind a red light is queued at it, not gridlocked [m].
RED_QUEUE_M = 250.0
#: Lane actuation: a controller's lane request (a change, or keeping the lane against
#: SUMO's strategy) is honoured while the lane it keeps or moves to lets the vehicle go
#: on along its route, with room for the lane changes still needed from there, this long
#: at its speed per change (and at least `LANE_CHOICE_RESERVE_M` per change); nearer,
#: SUMO's strategic lane change chooses (a follower keeping its lane behind the wrong
#: vehicle would otherwise miss its route) [s].
LANE_CHOICE_RESERVE_S = 6.0
#: [m] see `LANE_CHOICE_RESERVE_S`.
LANE_CHOICE_RESERVE_M = 50.0


def write_car_following_types(path: Path, types: dict[str, dict[str, str]]) -> Path:
    """An additional file with one vehicle type per id in `types`, each with the
    attributes given (`carFollowModel` and the model's parameters): the bases that
    `SumoBackend.add_vehicle_type` copies, since libsumo can set every attribute of a
    type but its car-following model."""
    root = ET.Element("additional")
    for type_id, attributes in types.items():
        ET.SubElement(root, "vType", {"id": type_id, **attributes})
    ET.indent(root)
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="unicode", xml_declaration=False)
    return path


def sumo_binary(name: str = "sumo") -> str:
    """Path of a SUMO executable shipped in the eclipse-sumo wheel (no SUMO_HOME needed)."""
    path = os.path.join(sumo.SUMO_HOME, "bin", name)
    if not os.path.exists(path):
        raise SumoError(f"SUMO executable '{name}' not found in {sumo.SUMO_HOME}/bin")
    return path


def gui_display_problem() -> str | None:
    """Why sumo-gui cannot open a window here (None when a display is set)."""
    if os.environ.get("DISPLAY"):
        return None
    return (
        "sumo-gui needs a display and none is set (DISPLAY); on a machine without one, "
        "run under a virtual display: xvfb-run -a platoon-sumo run ... --gui"
    )


def sumo_home() -> str:
    return str(sumo.SUMO_HOME)


def sumo_version() -> str:
    return str(libsumo.getVersion()[1])


@dataclass(frozen=True)
class SumoOptions:
    """Everything `SumoBackend.start` passes to SUMO."""

    net_file: str
    step_s: float
    seed: int
    begin_s: float = 0.0
    route_files: tuple[str, ...] = ()
    additional_files: tuple[str, ...] = ()
    lateral_resolution_m: float | None = 0.8
    time_to_teleport_s: float | None = None
    demand_scale: float = 1.0
    tripinfo_file: str | None = None
    statistics_file: str | None = None
    extra_args: tuple[str, ...] = ()
    gui: bool = False
    """Run sumo-gui (driven over TraCI) instead of libsumo's SUMO: the live view."""
    gui_delay_ms: float = 0.0
    """The live view's pause between steps [ms] (sumo-gui's `--delay`)."""

    def command(self) -> list[str]:
        cmd = [
            sumo_binary("sumo-gui" if self.gui else "sumo"),
            "--net-file", self.net_file,
            "--step-length", repr(self.step_s),
            "--begin", repr(self.begin_s),
            "--seed", str(self.seed),
            "--time-to-teleport",
            "-1" if self.time_to_teleport_s is None else repr(self.time_to_teleport_s),
            "--collision.action", "warn",
            "--collision.check-junctions", "true",
            "--no-step-log", "true",
            "--no-warnings", "true",
            # a collision is a real overlap, not a gap below minGap (platoons drive closer)
            "--collision.mingap-factor", "0",
            "--duration-log.disable", "true",
            "--xml-validation", "never",
        ]  # fmt: skip
        if self.demand_scale != 1.0:
            cmd += ["--scale", repr(self.demand_scale)]
        if self.lateral_resolution_m is not None:
            cmd += ["--lateral-resolution", repr(self.lateral_resolution_m)]
        if self.route_files:
            cmd += ["--route-files", ",".join(self.route_files)]
        if self.additional_files:
            cmd += ["--additional-files", ",".join(self.additional_files)]
        if self.tripinfo_file:
            cmd += ["--tripinfo-output", self.tripinfo_file]
            cmd += ["--tripinfo-output.write-unfinished", "true"]
        if self.statistics_file:
            cmd += ["--statistic-output", self.statistics_file]
        if self.gui:  # start at once, close with the run, no dialog on exit
            cmd += ["--start", "--quit-on-end", "--delay", repr(float(self.gui_delay_ms))]
            cmd += ["--window-size", "1280,800"]
        return [*cmd, *self.extra_args]


class SumoBackend:
    """One running SUMO simulation (libsumo allows only one per process).

    With `options.gui` the same calls go over TraCI to sumo-gui (the `traci` client has
    libsumo's API): slower, for watching, with the same results."""

    def __init__(self, options: SumoOptions):
        self.options = options
        self._api: _Libsumo | _GuiConnection = _Libsumo()
        if options.gui:
            import traci

            self._api = _GuiConnection(traci)
        self._running = False
        self._geometry: dict[str, tuple[float, float]] = {}
        self._min_gaps: dict[str, float] = {}
        self._lane_grid: _LaneGrid | None = None
        self._listable: tuple[int, NDArray[np.bool_]] | None = None
        """The lanes the world read lists, for how many vehicle types had entered."""
        self._lane_lengths: dict[str, float] = {}
        self._fit_widths: dict[str, float] = {}
        self._lane_signals: dict[str, tuple[str, str, int]] = {}
        """Per vehicle: its lane and the light (id, link index) at that lane's end."""
        self._tls_states: dict[str, str] = {}
        self._last_read: WorldSnapshot | None = None
        """This step's world read (None once SUMO stepped): its lanes and speeds are
        SUMO's until the next step, so the route's reads take them from it."""
        self._lane_positions: dict[str, float] = {}
        """This step's lane positions read by `route_contexts` (cleared when SUMO steps):
        SUMO's until the next step, so the actuation takes them from here."""
        self._polylines: dict[str, tuple[list[float], list[float], list[float], float]] = {}
        self._bends: dict[str, tuple[list[float], list[float]]] = {}
        self._lanes_behind: dict[str, list[str]] = {}
        """Sublane actuation: the lanes each platoon vehicle drove along, newest first (one
        per edge: a lane change replaces the lane of the edge)."""
        self._fronts: dict[str, tuple[str, float]] = {}
        """Sublane actuation: this step's lane and front bumper position on it (SUMO's
        lane position), read by `body_directions` for `in_junctions` and `lane_room`."""
        self._lane_edges: dict[str, str] = {}
        self._lane_counts: dict[str, int] = {}
        self._lane_widths: dict[str, float] = {}
        self._lateral_held: set[str] = set()
        """Sublane actuation: vehicles SUMO steers whose lateral move is held this step
        (`hold_lateral`)."""
        self._handed_over: set[str] = set()
        self._slow_since: dict[str, float] = {}
        """Sublane actuation: vehicles whose lane change SUMO makes (`_hand_over`)."""
        self._kept_on: dict[str, str] = {}
        """Sublane actuation: vehicles handed over for a lane change their route needs,
        with the edge it is on (SUMO keeps them to that edge's end)."""
        self._route_lanes: dict[str, tuple[str, dict[str, tuple[float, int]]]] = {}
        """Lane actuation: per vehicle, its edge and SUMO's best lanes there (lane id:
        length the route can be followed from the lane's start, lane changes still
        needed), read once per edge."""
        self._type_classes: dict[str, str] = {}
        self._largest_m = 0.0
        self._in_network = 0
        self._departed: tuple[str, ...] = ()
        self._known_gone: set[str] = set()
        """This step's arrivals read by the loop and the vehicles it removed itself."""

    def start(self) -> None:
        if self.options.gui and (problem := gui_display_problem()):
            raise SumoError(problem)
        try:
            self._api.start(self.options.command())
        except (self._api.TraCIException, self._api.FatalTraCIError) as exc:
            raise SumoError(f"SUMO did not start: {exc}") from None
        self._running = True

    def close(self) -> None:
        if self._running:
            self._running = False
            closed = (self._api.TraCIException, self._api.FatalTraCIError, SumoError)
            with contextlib.suppress(*closed):  # SUMO may be gone already
                self._api.close()

    def __enter__(self) -> SumoBackend:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def time_s(self) -> float:
        return float(self._api.simulation.getTime())

    def step(self) -> None:
        self._last_read = None
        self._lane_positions.clear()
        try:
            self._api.simulationStep()
        except self._api.TraCIException as exc:
            raise SumoError(f"SUMO failed at t={self.time_s:.2f} s: {exc}") from None
        veh, classes = self._api.vehicle, self._type_classes
        departed = self._departed = tuple(self._api.simulation.getDepartedIDList())
        self._in_network += len(departed) - self._api.simulation.getArrivedNumber()
        for vid in departed:
            type_id = veh.getTypeID(vid)
            if type_id not in classes:  # a type's first vehicle: its size and class
                vt = self._api.vehicletype
                size = float(vt.getLength(type_id) + vt.getWidth(type_id))
                self._largest_m = max(self._largest_m, size)
                classes[type_id] = str(vt.getVehicleClass(type_id))

    def snapshot(self, vehicle_ids: Sequence[str], radius_m: float) -> WorldSnapshot:
        """The given vehicles and every vehicle whose front bumper lies within `radius_m`
        of one of theirs (plain getters: the fastest reads in libsumo).

        Candidates come from the lanes near the vehicles (a grid over the lanes' shapes
        built once), each known with its lane from the lane's listing; only their
        positions are read before the distance filter, so the cost follows the traffic
        around the platoons, not the network's size."""
        veh = self._api.vehicle
        wanted = list(dict.fromkeys(vehicle_ids))
        if not wanted:
            return _empty_world(self.time_s)
        position = veh.getPosition
        centres = _points(map(position, wanted), len(wanted))
        listing = self._api.lane.getLastStepVehicleIDs
        lane_of: dict[str, str] = {}  # each vehicle's lane, in the order first listed
        for lane in self._lanes_near(centres, radius_m):
            for vid in listing(lane):
                lane_of.setdefault(vid, lane)
        # SUMO lists a vehicle on the lane its front is on, and that lane is near it; a
        # given vehicle on none (teleporting) is asked
        lanes_wanted = [lane_of.get(vid) or veh.getLaneID(vid) for vid in wanted]
        given = set(wanted)
        others = [vid for vid in lane_of if vid not in given]
        other_lanes = [lane_of[vid] for vid in others]
        near: list[int] = []
        if others:
            positions = _points(map(position, others), len(others))
            near = np.flatnonzero(within_radius(centres, positions, radius_m)).tolist()
            centres = np.concatenate([centres, positions[near]])
        ids = (*wanted, *(others[k] for k in near))
        lanes = (*lanes_wanted, *(other_lanes[k] for k in near))
        world = self._last_read = self._read(ids, centres, lanes)
        return world

    def _read(
        self, ids: tuple[str, ...], positions: NDArray[np.float64], lanes: tuple[str, ...]
    ) -> WorldSnapshot:
        veh = self._api.vehicle
        n = len(ids)
        get_angle, get_speed, geometry = veh.getAngle, veh.getSpeed, self._geometry
        angle = np.fromiter(map(get_angle, ids), np.float64, n)
        speed = np.fromiter(map(get_speed, ids), np.float64, n)
        dims = _points((geometry.get(vid) or self._size(vid) for vid in ids), n)
        return WorldSnapshot(
            time_s=self.time_s,
            ids=ids,
            front_x_m=positions[:, 0].copy(),
            front_y_m=positions[:, 1].copy(),
            yaw_rad=np.radians(90.0 - angle),
            length_m=dims[:, 0],
            width_m=dims[:, 1],
            speed_mps=speed,
            lane_ids=lanes,
            index=dict(zip(ids, range(n), strict=True)),
        )

    def _lanes_near(self, points: NDArray[np.float64], radius_m: float) -> list[str]:
        """Lanes (internal ones included) with a shape segment within `radius_m` of a
        point (conservatively: by grid cell), in a fixed order; only lanes that allow a
        vehicle class that has entered the network (no vehicle is on a lane it may not
        use: sidewalks, crossings and walking areas, a third of the lanes of an OSM
        city with footways, are never listed while no vehicle of a pedestrian class
        drives)."""
        grid = self._lane_grid
        if grid is None:
            grid = self._lane_grid = _LaneGrid.build(self._api, _LANE_CELL_M)
        classes = self._type_classes  # grows by a type at its first departure
        if self._listable is None or self._listable[0] != len(classes):
            self._listable = (len(classes), grid.listable(frozenset(classes.values())))
        return grid.near(points, radius_m, self._listable[1])

    def vehicle_count(self) -> int:
        """Vehicles in the network: departed minus arrived and removed, counted at each
        step (SUMO's own count lists every vehicle, a cost that grows with the network).
        A vehicle being teleported counts; SUMO's list leaves it out."""
        return self._in_network

    def standing_vehicles(self, min_wait_s: float) -> list[tuple[str, str, float, float, float]]:
        """Vehicles standing still (SUMO's waiting time: below 0.1 m/s since) for at
        least `min_wait_s`, neither stopped by their schedule (a stop, parking) nor
        within `RED_QUEUE_M` of a light ahead showing red, red-yellow or yellow (a queue
        at a light): (id, lane, x, y, seconds)."""
        veh = self._api.vehicle
        found = []
        for vid in veh.getIDList():
            waited = veh.getWaitingTime(vid)
            if waited < min_wait_s or veh.isStopped(vid):
                continue
            signals = veh.getNextTLS(vid)
            if signals and signals[0][2] <= RED_QUEUE_M and signals[0][3] in STOP_STATES:
                continue
            x, y = veh.getPosition(vid)
            found.append((vid, veh.getLaneID(vid), float(x), float(y), float(waited)))
        return found

    def vehicle_classes(self) -> dict[str, str]:
        """{vehicle type: its SUMO vClass} of every type that entered the network."""
        return dict(self._type_classes)

    def largest_vehicle_m(self) -> float:
        """Largest length + width [m] of the vehicle types that have entered the network
        (the types of departing vehicles are read after each step; SUMO's unused
        built-in types, such as a 135 m train, do not count)."""
        return self._largest_m

    def add_vehicle(
        self,
        vehicle_id: str,
        edges: Sequence[str],
        type_id: str,
        depart_lane: int,
        depart_pos_m: float,
        sumo_drives: bool,
        steers: bool = False,
        depart_speed_mps: float = 0.0,
    ) -> None:
        """Ask SUMO to insert a platoon vehicle now; it appears once there is room.

        `sumo_drives`: SUMO's safe speed, lights and right of way cap our speed command.
        Without `steers` (lane actuation) SUMO keeps the vehicle in its lanes and makes
        the route's lane changes, none of its own accord (speed gain, keeping right,
        cooperation) so members stay in one lane; with it (sublane actuation) only our
        sideways requests move it."""
        route_id = f"route_{vehicle_id}"
        try:
            self._api.route.add(route_id, list(edges))
            self._api.vehicle.add(
                vehicle_id,
                route_id,
                typeID=type_id,
                depart="now",
                departLane=str(depart_lane),
                departPos=repr(depart_pos_m),
                departSpeed=repr(depart_speed_mps),
            )
            if sumo_drives:
                mode = LANE_CHANGE_REQUESTS_ONLY if steers else LANE_CHANGE_STRATEGIC_ONLY
                self._api.vehicle.setLaneChangeMode(vehicle_id, mode)
            else:  # we place it: SUMO must neither brake it nor change its lane
                self._api.vehicle.setSpeedMode(vehicle_id, 0)
                self._api.vehicle.setLaneChangeMode(vehicle_id, 0)
        except self._api.TraCIException as exc:
            raise SumoError(f"cannot insert vehicle '{vehicle_id}': {exc}") from None

    def add_vehicle_type(
        self,
        type_id: str,
        length_m: float,
        width_m: float,
        min_gap_m: float,
        max_speed_mps: float,
        accel_mps2: float,
        decel_mps2: float,
        vclass: str,
        tau_s: float = 1.0,
        speed_factor: float | None = None,
        base_type: str = "DEFAULT_VEHTYPE",
    ) -> None:
        """A SUMO type for platoon vehicles, so SUMO's drivers see their true size; without
        driver imperfection, and with `tau_s` for SUMO's safe speed in lane actuation.
        `speed_factor`: every vehicle's factor on lane speed limits, without spread (None:
        drawn per vehicle as for SUMO's default type). `base_type`: the type copied, with
        its car-following model (libsumo cannot set a model: `write_car_following_types`)."""
        vt = self._api.vehicletype
        try:
            vt.copy(base_type, type_id)
            vt.setVehicleClass(type_id, vclass)
            vt.setLength(type_id, length_m)
            vt.setWidth(type_id, width_m)
            vt.setMinGap(type_id, min_gap_m)
            vt.setMaxSpeed(type_id, max_speed_mps)
            vt.setAccel(type_id, accel_mps2)
            vt.setDecel(type_id, decel_mps2)
            vt.setEmergencyDecel(type_id, max(decel_mps2, vt.getEmergencyDecel(type_id)))
            vt.setTau(type_id, tau_s)
            vt.setImperfection(type_id, 0.0)
            if speed_factor is not None:
                vt.setSpeedFactor(type_id, speed_factor)
                vt.setSpeedDeviation(type_id, 0.0)
            vt.setColor(type_id, (30, 120, 255, 255))
        except Exception as exc:  # libsumo raises FatalTraCIError for some bad values
            raise SumoError(f"cannot create vehicle type '{type_id}': {exc}") from None

    def lane_is_free(self, lane_id: str, from_m: float, to_m: float) -> bool:
        """No vehicle's footprint overlaps [from_m, to_m] along the lane (positions from the
        lane start; a vehicle spans [pos - length, pos])."""
        for vid in self._api.lane.getLastStepVehicleIDs(lane_id):
            front = self._api.vehicle.getLanePosition(vid)
            if front > from_m and front - self._api.vehicle.getLength(vid) < to_m:
                return False
        return True

    def lane_occupants(self, lane_id: str) -> list[tuple[str, float, float, float]]:
        """(id, front position along the lane, speed, length) of every vehicle on the lane."""
        veh = self._api.vehicle
        return [
            (vid, veh.getLanePosition(vid), veh.getSpeed(vid), veh.getLength(vid))
            for vid in self._api.lane.getLastStepVehicleIDs(lane_id)
        ]

    def next_junction_lane(self, vehicle_id: str) -> str:
        """The lane the vehicle enters at the end of its current lane (the link's
        internal lane, or the next lane where the link has none); "" at its route's end."""
        links = self._api.vehicle.getNextLinks(vehicle_id)
        if not links:
            return ""
        return str(links[0][4] or links[0][0])

    def lane_shape(self, lane_id: str) -> NDArray[np.float64]:
        """The lane's centre-line, (n, 2) network coordinates."""
        return np.asarray(self._api.lane.getShape(lane_id), dtype=np.float64).reshape(-1, 2)

    def lane_width(self, lane_id: str) -> float:
        width = self._lane_widths.get(lane_id)
        if width is None:
            width = self._lane_widths[lane_id] = float(self._api.lane.getWidth(lane_id))
        return width

    def departed_ids(self) -> tuple[str, ...]:
        """Vehicles SUMO inserted in the last step (read once, in `step`)."""
        return self._departed

    def arrived_ids(self) -> tuple[str, ...]:
        arrived = tuple(self._api.simulation.getArrivedIDList())
        for vid in arrived:
            self._forget(vid)
        self._known_gone = set(arrived)
        return arrived

    def removed_elsewhere(self) -> tuple[str, ...]:
        """Vehicles taken out of SUMO since the last step's arrivals were read, by
        someone else (a hook or plug-in calling libsumo): SUMO lists them with that
        step's arrivals until the next step."""
        gone = tuple(
            vid for vid in self._api.simulation.getArrivedIDList() if vid not in self._known_gone
        )
        for vid in gone:
            self._forget(vid)
        self._known_gone.update(gone)
        self._in_network -= len(gone)
        return gone

    def teleported_ids(self) -> tuple[str, ...]:
        """Vehicles SUMO started to teleport in the last step."""
        return tuple(self._api.simulation.getStartingTeleportIDList())

    def move(
        self,
        vehicle_ids: Sequence[str],
        front_x_m: NDArray[np.float64],
        front_y_m: NDArray[np.float64],
        yaw_rad: NDArray[np.float64],
        speed_mps: NDArray[np.float64],
    ) -> dict[str, str]:
        """Place platoon vehicles at the next step (front bumper, SUMO's angle convention).

        Returns the vehicles SUMO could not place on their route, with SUMO's reason; the
        caller decides what happens to them (one lost vehicle must not end a long run)."""
        angles = (90.0 - np.degrees(yaw_rad)) % 360.0
        veh = self._api.vehicle
        failed: dict[str, str] = {}
        for i, vid in enumerate(vehicle_ids):
            try:
                veh.moveToXY(vid, "", -1, float(front_x_m[i]), float(front_y_m[i]),
                             float(angles[i]), keepRoute=1)  # fmt: skip
                veh.setPreviousSpeed(vid, float(speed_mps[i]))
            except self._api.TraCIException as exc:
                failed[vid] = (
                    f"cannot place '{vid}' at ({front_x_m[i]:.2f}, {front_y_m[i]:.2f}) "
                    f"at t={self.time_s:.2f} s: {exc}"
                )
        return failed

    def set_speeds(self, vehicle_ids: Sequence[str], speed_mps: NDArray[np.float64]) -> None:
        """Speed commands for SUMO-driven (lane actuation) platoon vehicles, next step; a
        negative speed gives the vehicle's speed back to its type's car-following model."""
        veh = self._api.vehicle
        for vid, speed in zip(vehicle_ids, speed_mps, strict=True):
            veh.setSpeed(vid, float(speed))

    def request_lane_changes(self, requests: dict[str, int]) -> None:
        """Lane actuation: ask SUMO to change each vehicle one lane left (+1) or right (-1),
        or to keep its lane (0: SUMO's own lane changes wait).

        SUMO makes the change when the target lane's gap is safe (lane-change mode). A
        request is dropped, as a driver would, for a lane that does not exist or from
        which the route cannot be followed on with the room `LANE_CHOICE_RESERVE_S`
        gives (SUMO's strategy then picks the lane)."""
        veh = self._api.vehicle
        for vid, direction in requests.items():
            lane_id = self._lane_now(vid)
            if not lane_id or lane_id.startswith(":"):
                continue
            edge = self._lane_edge(lane_id)
            lane = int(lane_id[len(edge) + 1 :]) + direction  # a lane's id: <edge>_<index>
            best = self._best_lanes(vid, edge).get(f"{edge}_{lane}")
            if best is None:  # no such lane, or not one SUMO's route planning knows
                continue
            length_m, changes = best
            if changes:
                reserve = max(LANE_CHOICE_RESERVE_M, LANE_CHOICE_RESERVE_S * veh.getSpeed(vid))
                if length_m - self._position_now(vid) < abs(changes) * reserve:
                    continue
            # for one step: re-issued while the controller asks, never carried onto the
            # next edge (where that index may lead elsewhere)
            veh.changeLane(vid, lane, self.options.step_s)

    def _best_lanes(self, vid: str, edge: str) -> dict[str, tuple[float, int]]:
        """SUMO's best lanes of the vehicle's edge (`_route_lanes`), read once per edge."""
        known = self._route_lanes.get(vid)
        if known is None or known[0] != edge:
            lanes = {
                str(lane): (float(length), int(offset))
                for lane, length, _, offset, _, _ in self._api.vehicle.getBestLanes(vid)
            }
            known = self._route_lanes[vid] = (edge, lanes)
        return known[1]

    def set_lateral_speeds(
        self, vehicle_ids: Sequence[str], speed_mps: NDArray[np.float64]
    ) -> None:
        """Sublane actuation: move each vehicle sideways (left +) at this speed in the next
        step. SUMO's lateral move runs at most the vehicle's `maxSpeedLat` and no faster
        than it could stop at the offset asked for, so the speed is set as that limit
        and the offset asked for lies well beyond (re-asked every step; 0 stops it).

        A slow vehicle on a lane from which its route cannot go on within
        `LANE_END_REACH_M` (SUMO's best lanes) is handed to SUMO's own lane change
        instead (`_hand_over`) until it is on a lane that continues, near its centre."""
        veh = self._api.vehicle
        for vid in self._lateral_held:  # held for one step only
            if vid in self._handed_over:
                veh.setMaxSpeedLat(vid, HANDED_OVER_LATERAL_MPS)
        self._lateral_held.clear()
        for vid, speed in zip(vehicle_ids, speed_mps.tolist(), strict=True):
            if self._hand_over(vid):
                continue
            magnitude = abs(speed)
            if magnitude < MIN_LATERAL_SPEED_MPS:
                veh.changeSublane(vid, 0.0)
                continue
            veh.setMaxSpeedLat(vid, magnitude)
            reach = max(LATERAL_REACH_M, magnitude * magnitude)
            veh.changeSublane(vid, reach if speed > 0 else -reach)

    def lane_room(
        self, vehicle_ids: Sequence[str]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Per vehicle: its lateral offset from its lane's centre (left +) [m]; how far
        that offset may go either side with the body inside the lane and inside every
        lane the lane leads to [m]; and the distance from its front bumper to the lane's
        end [m]. SUMO lets a sublane car onto the next lane only with its body inside it:
        a car that entered a junction 1.5 m beside its lane's centre stood at the
        junction's exit for good (the `highway` game network, seed 44). A vehicle on no
        lane gets 0, an unbounded room and distance."""
        veh = self._api.vehicle
        n = len(vehicle_ids)
        offset, room, to_end = np.zeros(n), np.full(n, math.inf), np.full(n, math.inf)
        for i, vid in enumerate(vehicle_ids):
            known = self._fronts.get(vid)  # read by `body_directions` this step
            lane_id, front = known if known is not None else (self._lane_now(vid), None)
            if not lane_id:
                continue
            width = self._size(vid)[1]
            offset[i] = veh.getLateralLanePosition(vid)
            room[i] = max(0.5 * (self._fit_width(lane_id) - width), 0.0)
            if front is None:
                front = self._position_now(vid)
            to_end[i] = self._lane_length(lane_id) - front
        return offset, room, to_end

    def bends_ahead(
        self, vehicle_ids: Sequence[str]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Sublane actuation, per car and for each of the next `BENDS_AHEAD` sharp bends
        of its lane's shape ahead of its front bumper (columns, nearest first): how far
        [m] from the lane's centre the front may cross it without SUMO moving the car
        more than `LANDING_SHIFT_M` there, and the distance to it [m]; unbounded where
        the rest of the lane has no more such bends, or the car is on no lane or in a
        junction. Call `body_directions` first in the same step.

        SUMO puts a car's front at its lateral offset square to the shape's segment
        under it: crossing a vertex where the shape turns by an angle a, a car d beside
        the centre line moves 2 d sin(a / 2) at once, forward on the outside of the
        bend and back on the inside. On the race circuit's invented on-ramp (10 m
        lanes, a 30 degree vertex) a follower 3.5 m left of its lane's centre jumped
        2.3 m onto its leader (seed 42, 220.2 s)."""
        n = len(vehicle_ids)
        room = np.full((n, BENDS_AHEAD), math.inf)
        to_bend = np.full((n, BENDS_AHEAD), math.inf)
        for i, vid in enumerate(vehicle_ids):
            known = self._fronts.get(vid)
            if known is None or known[0].startswith(":"):
                continue
            lane_id, front = known
            positions, rooms = self._sharp_bends(lane_id)
            k = bisect.bisect_right(positions, front)  # SUMO: a front on a vertex is past it
            for c, j in enumerate(range(k, min(k + BENDS_AHEAD, len(positions)))):
                room[i, c], to_bend[i, c] = rooms[j], positions[j] - front
        return room, to_bend

    def _sharp_bends(self, lane_id: str) -> tuple[list[float], list[float]]:
        """The lane positions of the bends of a lane's shape where a car within half the
        lane's width of its centre could be moved more than `LANDING_SHIFT_M` (see
        `bends_ahead`), and the largest offset that is not. Vertices within
        `BEND_MERGE_M` of each other are one bend (a car may cross them in one step),
        turning by the larger of their sum and their largest turn."""
        cached = self._bends.get(lane_id)
        if cached is None:
            xs, ys, cum, scale = self._lane_polyline(lane_id)
            # segments of some length, their directions, and the turns between them
            kept = [j for j in range(len(xs) - 1) if cum[j + 1] - cum[j] > 1e-9]
            angles = [math.atan2(ys[j + 1] - ys[j], xs[j + 1] - xs[j]) for j in kept]
            vertices = [
                (cum[kept[k]] / scale, math.remainder(angles[k] - angles[k - 1], math.tau))
                for k in range(1, len(kept))
            ]
            groups: list[tuple[float, float, float]] = []  # position, sum, largest turn
            for at, turn in vertices:
                if groups and at - groups[-1][0] <= BEND_MERGE_M:
                    first, total, largest = groups[-1]
                    groups[-1] = (first, total + turn, max(largest, abs(turn)))
                else:
                    groups.append((at, turn, abs(turn)))
            half = 0.5 * self.lane_width(lane_id)
            positions: list[float] = []
            rooms: list[float] = []
            for at, total, largest in groups:
                turn = min(max(abs(total), largest), math.pi)
                bound = LANDING_SHIFT_M / (2.0 * math.sin(0.5 * turn)) if turn else math.inf
                if bound < half:
                    positions.append(at)
                    rooms.append(bound)
            cached = self._bends[lane_id] = (positions, rooms)
        return cached

    def _fit_width(self, lane_id: str) -> float:
        """The narrowest of a lane and the lanes its links lead to (through and beyond a
        junction's internal lanes) [m]."""
        width = self._fit_widths.get(lane_id)
        if width is None:
            lane = self._api.lane
            widths = [float(lane.getWidth(lane_id))]
            for link in lane.getLinks(lane_id):
                widths += [float(lane.getWidth(str(k))) for k in (link[0], link[4]) if k]
            width = self._fit_widths[lane_id] = min(widths)
        return width

    def _hand_over(self, vid: str) -> bool:
        """Should SUMO make this sublane-actuated vehicle's lane change now?

        Our steering moves a car sideways only as it drives forward (a kinematic model).
        A car that a queue or the end of its lane holds on a lane its route cannot
        continue from would stand there for good; so would one that our gap check holds
        before a change into a lane whose queue never leaves a gap (SUMO's drivers make
        room only for a change SUMO knows of). Such a car, slower than
        `HAND_OVER_BELOW_MPS` with the route leaving its lane within `LANE_END_REACH_M`,
        or slow for `HAND_OVER_AFTER_S` with the route leaving its lane on this edge,
        gets the lane-change mode of lane actuation: SUMO changes to the lane its route
        needs when the gap there is safe, sideways even at a standstill, and centres it
        there. So does a car at any speed whose route needs a sideways move steeper
        than it can steer comfortably (`_too_steep`: a short edge where netconvert
        invented a ramp, a lane drop, a change forced within a few metres).

        SUMO keeps a car handed over for its route's lane change to the end of that
        edge, then centres it on a lane that continues (within `HANDED_BACK_WITHIN_M`)
        before our steering (mode 0) takes it back. Given back on the target lane
        mid-edge, our steering followed what is still across the lanes there: the
        route path, or the predecessor a laser follower tracks, itself waiting on the
        lane between for a gap (a follower handed over at 2 m/s, given back on its
        target lane, steered back across at 2.2 m/s sideways)."""
        veh = self._api.vehicle
        handed = vid in self._handed_over
        lane_id = self._lane_now(vid)
        speed = veh.getSpeed(vid)
        if speed < HAND_OVER_BELOW_MPS:
            slow_s = self.time_s - self._slow_since.setdefault(vid, self.time_s)
        else:
            self._slow_since.pop(vid, None)
            slow_s = -1.0
        if not lane_id or lane_id.startswith(":"):
            # inside a junction no lane change is made: our steering fits the body into
            # the lane ahead (`fit_ahead`), which SUMO does not do for its own
            # move (a car it drove in 2.3 m beside the centre stood at the exit for good)
            needs = False
        else:
            edge = self._lane_edge(lane_id)
            if self._kept_on.get(vid, edge) != edge:
                del self._kept_on[vid]  # past the edge of its lane change
            needs = vid in self._kept_on
            if not needs:
                position = self._position_now(vid)
                reach = math.inf if handed else LANE_END_REACH_M
                waited = handed or slow_s >= HAND_OVER_AFTER_S
                own_end = self._lane_length(lane_id) + 0.1
                for lane, length, _, offset, _, _ in veh.getBestLanes(vid):
                    if lane != lane_id or offset == 0:
                        continue
                    if handed or slow_s >= 0.0:
                        needs = length - position < reach or (waited and length < own_end)
                    if not needs:
                        needs = self._too_steep(vid, lane_id, offset, length - position)
                    if needs:
                        self._kept_on[vid] = edge
                    break
                if handed and not needs:
                    needs = abs(veh.getLateralLanePosition(vid)) > HANDED_BACK_WITHIN_M
        if needs and not handed:
            veh.changeSublane(vid, 0.0)  # our last request would still win over SUMO's
            veh.setLaneChangeMode(vid, LANE_CHANGE_STRATEGIC_ONLY)
            veh.setMaxSpeedLat(vid, HANDED_OVER_LATERAL_MPS)
            self._handed_over.add(vid)
        elif handed and not needs:
            veh.setLaneChangeMode(vid, LANE_CHANGE_REQUESTS_ONLY)
            self._handed_over.discard(vid)
        return needs

    def sumo_lateral_speeds(
        self, vehicle_ids: Sequence[str], offset_m: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Sublane actuation: the sideways speed (left +) SUMO may move each car it steers
        (`_hand_over`) at in the next step: `HANDED_OVER_LATERAL_MPS` the way it moves
        now, or towards the nearer edge of its lane (`offset_m`, from `lane_room`) while
        it does not; NaN for the cars we steer. The cars handed over are those of the
        last step (`set_lateral_speeds` hands over and back)."""
        veh = self._api.vehicle
        out = np.full(len(vehicle_ids), np.nan)
        for i, vid in enumerate(vehicle_ids):
            if vid in self._handed_over:
                now = veh.getLateralSpeed(vid)
                out[i] = math.copysign(HANDED_OVER_LATERAL_MPS, now if now else offset_m[i])
        return out

    def lane_change_landings(
        self,
        vehicle_ids: Sequence[str],
        offset_m: NDArray[np.float64],
        lateral_mps: NDArray[np.float64],
        speed_mps: NDArray[np.float64],
        dt_s: float,
    ) -> NDArray[np.float64]:
        """Sublane actuation: for each car whose sideways move (`lateral_mps`, left +)
        crosses into the next lane of its edge in this step, where SUMO will put it down
        when that is not beside where it drives to: its footprint (centre x, y, yaw,
        length, width; turned as now); NaN rows for the others. `offset_m` are the
        lateral offsets (`lane_room`, call it first in the same step) and `speed_mps` the
        speeds the cars reach in the step.

        SUMO's sublane model changes a car's lane when its centre crosses the lane's edge
        and keeps its lane position: where the lanes of an edge are not side by side at
        one lane position (a tight curve with lanes of different lengths, a ramp
        netconvert added) the car jumps along the road, onto whatever is there: on the
        race circuit's invented on-ramp (four 10 m lanes) a leader SUMO moved over at
        1 m/s jumped 4.5 m back onto its follower (seed 44, 175.1 s)."""
        veh = self._api.vehicle
        out = np.full((len(vehicle_ids), 5), np.nan)
        for i, vid in enumerate(vehicle_ids):
            known = self._fronts.get(vid)
            if known is None or known[0].startswith(":"):
                continue  # no lane, or inside a junction: no lane change
            lane_id, front = known
            half = 0.5 * self.lane_width(lane_id)
            lateral = float(offset_m[i] + lateral_mps[i] * dt_s)
            if abs(lateral) <= half:
                continue
            direction = 1 if lateral > 0.0 else -1
            edge = self._lane_edge(lane_id)
            index = int(lane_id[len(edge) + 1 :]) + direction
            if not 0 <= index < self._lane_count(edge):
                continue
            target = f"{edge}_{index}"
            position = min(front + float(speed_mps[i]) * dt_s, self._lane_length(lane_id))
            x, y = self._lane_point([lane_id], position, lateral)
            shift = lateral - direction * (half + 0.5 * self.lane_width(target))
            lx, ly = self._lane_point([target], position, shift)
            if math.hypot(lx - x, ly - y) <= LANDING_SHIFT_M:
                continue  # the lanes lie side by side here
            length, width = self._size(vid)
            # turned as now: SUMO's angle follows the lateral motion, not the lane there
            yaw = math.radians(90.0 - veh.getAngle(vid))
            half_length = 0.5 * length
            out[i] = (lx - half_length * math.cos(yaw), ly - half_length * math.sin(yaw),
                      yaw, length, width)  # fmt: skip
        return out

    def hold_lateral(self, vehicle_ids: Sequence[str]) -> None:
        """Sublane actuation, after `set_lateral_speeds` (which stops our own sideways
        moves with a lateral speed of 0): no sideways move in this step either for
        these cars that SUMO steers (`_hand_over`), its lane change waits."""
        veh = self._api.vehicle
        for vid in vehicle_ids:
            if vid in self._handed_over:
                veh.setMaxSpeedLat(vid, 0.0)
                self._lateral_held.add(vid)

    def sideways_waits(
        self, vehicle_ids: Sequence[str], leaders: Sequence[VehicleAhead | None]
    ) -> dict[str, tuple[str, float]]:
        """Which of these vehicles (with SUMO's leader of each) must stay behind a car
        SUMO is to move sideways across its path, with that car's id and the gap to its
        back along the lanes [m]. SUMO moves a car sideways only with a gap behind it
        on every sublane it enters (at a standstill, the follower's minGap, along the
        lanes), and our cars, driven by our speed commands, do not make that room as
        SUMO's drivers do. Two such cars:
        - one handed to SUMO's lane change (`_hand_over`), standing or creeping
          (slower than `HAND_OVER_BELOW_MPS`) on a lane its route leaves, with SUMO
          wanting the change now (not one a later edge needs: on `highway`, seed 44, a
          leader held back by our own gap check claimed the lane of the follower
          beside it, which stopped for it). Its path is the band from its body to the
          centre of the lane it needs; a vehicle level with its back or beyond, or
          beside the band, is not held. Race circuit, seed 43: a leader stood at the
          end of a ramp lane waiting to move left; its follower pulled up 0.5 m behind
          and 3 m to its left and waited in turn. Along the lanes, not in the plane:
          on that curve the gap SUMO checks was 1.9 m, the bodies 6 m apart;
        - SUMO's leader of a vehicle, moving or not, on a junction's internal lane with
          its body beyond the lane it goes on to (wider lanes before the junction than
          after it): SUMO lets a car leave a junction only with its body inside the
          next lane and moves it there at the exit. Race circuit, seed 44: a car stood
          3.1 m beside its lane's centre at a junction's exit, blocked by a platoon car
          0.5 m behind it, which waited for it. Not with a negative gap (level or
          beyond): that vehicle drives on, out of the car's way."""
        veh = self._api.vehicle
        bands: dict[str, list[tuple[float, float, float, str]]] = {}
        for vid in sorted(self._handed_over):
            lane_id = self._lane_now(vid)
            if not lane_id or lane_id[0] == ":" or veh.getSpeed(vid) >= HAND_OVER_BELOW_MPS:
                continue
            best = veh.getBestLanes(vid)
            offset = next((o for lane, _, _, o, _, _ in best if lane == lane_id), 0)
            if not offset:
                continue
            wish = veh.getLaneChangeState(vid, 1 if offset > 0 else -1)[0]
            if not wish & (LCA_LEFT if offset > 0 else LCA_RIGHT):
                continue  # SUMO does not want the change yet (a later edge needs it)
            edge, index, centre = self._across_edge(vid, lane_id)
            target = self._edge_lateral(edge, index + offset)
            length, width = self._size(vid)
            low, high = min(centre - 0.5 * width, target), max(centre + 0.5 * width, target)
            back = self._position_now(vid) - length
            bands.setdefault(edge, []).append((back, low, high, vid))
        waits: dict[str, tuple[str, float]] = {}
        for vid, leader in zip(vehicle_ids, leaders, strict=True):
            if leader is not None and leader.gap_m >= 0.0 and self._misfit(leader.vehicle_id):
                waits[vid] = (leader.vehicle_id, leader.gap_m)
        if not bands:
            return waits
        for vid in vehicle_ids:
            lane_id = self._lane_now(vid)
            if lane_id.rpartition("_")[0] not in bands:
                continue
            edge, _, centre = self._across_edge(vid, lane_id)
            front = self._position_now(vid)
            half = 0.5 * self._size(vid)[1]
            for back, low, high, other in bands[edge]:
                gap = back - front
                if other == vid or gap < 0.0 or centre + half <= low or centre - half >= high:
                    continue
                if vid not in waits or gap < waits[vid][1]:
                    waits[vid] = (other, gap)
        return waits

    def _misfit(self, vid: str) -> bool:
        """Is this car on a junction's internal lane with its body beyond the lanes it
        goes on to (more than `MISFIT_TOLERANCE_M`)? Moving or not: it will stop at the
        exit to move over (race circuit, seed 44: a car behind one that stopped there
        was already within the room when the other stood still)."""
        lane_id = self._lane_now(vid)
        if not lane_id.startswith(":"):
            return False
        room = 0.5 * (self._fit_width(lane_id) - self._size(vid)[1])
        lateral = self._api.vehicle.getLateralLanePosition(vid)
        return abs(lateral) > max(room, 0.0) + MISFIT_TOLERANCE_M

    def _size(self, vid: str) -> tuple[float, float]:
        """A vehicle's (length, width) [m], read once."""
        size = self._geometry.get(vid)
        if size is None:
            veh = self._api.vehicle
            size = self._geometry[vid] = (float(veh.getLength(vid)), float(veh.getWidth(vid)))
        return size

    def _across_edge(self, vid: str, lane_id: str) -> tuple[str, int, float]:
        """The edge of a vehicle's lane (SUMO's lane id: edge, "_", index), the lane's
        index, and where the vehicle's centre lies across the edge, from its right
        side [m]."""
        edge, _, index = lane_id.rpartition("_")
        lateral = self._api.vehicle.getLateralLanePosition(vid)
        return edge, int(index), self._edge_lateral(edge, int(index)) + lateral

    def _edge_lateral(self, edge: str, index: int) -> float:
        """Where the centre of an edge's lane lies across the edge, from its right
        side [m]."""
        widths = [self.lane_width(f"{edge}_{k}") for k in range(index + 1)]
        return sum(widths) - 0.5 * widths[-1]

    def _lane_count(self, edge: str) -> int:
        count = self._lane_counts.get(edge)
        if count is None:
            count = self._lane_counts[edge] = int(self._api.edge.getLaneNumber(edge))
        return count

    def _too_steep(self, vid: str, lane_id: str, offset: int, remaining_m: float) -> bool:
        """Would steering this car `offset` lanes over (left +) within `remaining_m`
        (where its route leaves its lane, SUMO's best lanes) cross the lanes steeper
        than `STEER_MAX_LANE_ANGLE_RAD` and faster sideways than
        `STEER_COMFORT_LATERAL_MPS` at its speed?"""
        veh = self._api.vehicle
        sideways = abs(offset) * float(self._api.lane.getWidth(lane_id)) - math.copysign(
            veh.getLateralLanePosition(vid), offset
        )
        speed = max(veh.getSpeed(vid), 1e-3)
        slope = max(STEER_MAX_LANE_TAN, STEER_COMFORT_LATERAL_MPS / speed)
        return sideways > slope * max(remaining_m, 0.0)

    def body_directions(
        self, vehicle_ids: Sequence[str], ahead_m: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """SUMO's angle of each vehicle without its sideways part [rad, counter-clockwise
        from +x], now and once the vehicle has moved `ahead_m` further along its lanes.

        SUMO's angle is the direction from the back to the front bumper, both placed on
        the centre-lines of the lanes the vehicle occupies (the back may be on the lanes
        it came from), turned by an angle that follows its lateral motion. The lanes
        behind are the ones this method saw the vehicle drive along, one per edge (call it
        every step); beyond them a lane's first or last segment is extended. A vehicle on no lane
        (teleporting) gets its own angle twice."""
        veh = self._api.vehicle
        now = np.empty(len(vehicle_ids))
        later = np.empty(len(vehicle_ids))
        for i, (vid, ahead) in enumerate(zip(vehicle_ids, ahead_m.tolist(), strict=True)):
            lane_id = self._lane_now(vid)
            if not lane_id:
                self._fronts.pop(vid, None)
                now[i] = later[i] = math.radians(90.0 - veh.getAngle(vid))
                continue
            lanes = self._lanes_behind.setdefault(vid, [])
            if not lanes or lanes[0] != lane_id:
                if lanes and self._lane_edge(lanes[0]) == self._lane_edge(lane_id):
                    lanes[0] = lane_id  # a lane change: the lanes behind stay behind
                else:
                    lanes.insert(0, lane_id)
                    del lanes[4:]
            length = self._size(vid)[0]
            front = self._position_now(vid)
            self._fronts[vid] = (lane_id, front)
            now[i] = self._chord(lanes, front, length)
            later[i] = self._chord(lanes, front + ahead, length)
        return now, later

    def in_junctions(self, vehicle_ids: Sequence[str]) -> NDArray[np.bool_]:
        """Has each vehicle any part of its body on a junction's internal lane (its front
        on one, or its back still on one of the lanes `body_directions` saw it drive
        along)? Call after `body_directions` in the same step (its reads are used)."""
        veh = self._api.vehicle
        out = np.zeros(len(vehicle_ids), dtype=np.bool_)
        for i, vid in enumerate(vehicle_ids):
            lanes = self._lanes_behind.get(vid)
            if not lanes:
                continue
            known = self._fronts.get(vid)
            front = known[1] if known is not None else veh.getLanePosition(vid)
            back = front - self._size(vid)[0]
            k = 0
            hit = lanes[0].startswith(":")
            while not hit and back < 0.0 and k + 1 < len(lanes):
                k += 1
                back += self._lane_length(lanes[k])
                hit = lanes[k].startswith(":")
            out[i] = hit
        return out

    def _chord(self, lanes: list[str], front_m: float, length_m: float) -> float:
        fx, fy = self._lane_point(lanes, front_m)
        bx, by = self._lane_point(lanes, front_m - length_m)
        return math.atan2(fy - by, fx - bx)

    def _lane_point(
        self, lanes: list[str], pos_m: float, offset_m: float = 0.0
    ) -> tuple[float, float]:
        """The point `pos_m` along lanes[0] (SUMO's lane positions), on the lanes before
        it (lanes[1:], newest first) when negative; `offset_m` left of it, beside the
        shape's segment there (where SUMO puts a front bumper at that lateral offset)."""
        k = 0
        while pos_m < 0.0 and k + 1 < len(lanes):
            k += 1
            pos_m += self._lane_length(lanes[k])
        xs, ys, cum, scale = self._lane_polyline(lanes[k])
        at = pos_m * scale
        # Python floats and bisect, not numpy: two points per platoon car per step, where
        # numpy's per-call overhead (np.clip on a scalar) was 4 % of a sublane run
        j = min(max(bisect.bisect_left(cum, at) - 1, 0), len(cum) - 2)
        seg = cum[j + 1] - cum[j]
        t = (at - cum[j]) / seg if seg > 0 else 0.0
        dx, dy = xs[j + 1] - xs[j], ys[j + 1] - ys[j]
        x, y = xs[j] + dx * t, ys[j] + dy * t
        if offset_m and seg > 0:
            x, y = x - dy / seg * offset_m, y + dx / seg * offset_m
        return x, y

    def _lane_polyline(self, lane_id: str) -> tuple[list[float], list[float], list[float], float]:
        """Shape (x and y), cumulative length along it, and shape length per unit of lane
        position (SUMO's lane length may differ from its shape's)."""
        cached = self._polylines.get(lane_id)
        if cached is None:
            xy = self.lane_shape(lane_id)
            cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
            length = self._lane_length(lane_id)
            scale = float(cum[-1] / length) if length > 0 else 1.0
            cached = (xy[:, 0].tolist(), xy[:, 1].tolist(), cum.tolist(), scale)
            self._polylines[lane_id] = cached
        return cached

    def remove(self, vehicle_id: str, arrived: bool) -> None:
        """Take a platoon vehicle out: at the end of its route as an arrival (tripinfo),
        or vaporised when SUMO can no longer place it."""
        constants = self._api.constants
        reason = constants.REMOVE_ARRIVED if arrived else constants.REMOVE_VAPORIZED
        try:
            on_road = bool(self._api.vehicle.getRoadID(vehicle_id))
            self._api.vehicle.remove(vehicle_id, reason)
        except self._api.TraCIException as exc:
            raise SumoError(f"cannot remove vehicle '{vehicle_id}': {exc}") from None
        self._in_network -= on_road  # SUMO does not count our removals as arrivals
        self._forget(vehicle_id)
        self._known_gone.add(vehicle_id)

    def _forget(self, vid: str) -> None:
        """Drop what is kept about a vehicle that left the network."""
        self._geometry.pop(vid, None)
        self._min_gaps.pop(vid, None)
        self._lanes_behind.pop(vid, None)
        self._fronts.pop(vid, None)
        self._handed_over.discard(vid)
        self._lateral_held.discard(vid)
        self._slow_since.pop(vid, None)
        self._kept_on.pop(vid, None)
        self._route_lanes.pop(vid, None)
        self._lane_signals.pop(vid, None)

    def junction_yields(self, vehicle_id: str) -> list[tuple[str, float]]:
        """The vehicles SUMO's right of way makes this one yield to at the junction
        ahead, the nearest on each conflicting junction lane (`getJunctionFoes`: foe,
        its distance to the conflict, its junction lane, the ego's response), with how
        long each has stood still (SUMO's waiting time)."""
        veh = self._api.vehicle
        first: dict[str, tuple[float, str]] = {}
        for f in veh.getJunctionFoes(vehicle_id, JUNCTION_FOES_M):
            foe, foe_m, foe_lane, yields = f[0], f[2], f[5], f[6]
            if yields and foe_m < first.get(foe_lane, (math.inf, ""))[0]:
                first[foe_lane] = (foe_m, foe)
        return [(foe, float(veh.getWaitingTime(foe))) for _, foe in first.values()]

    def take_right_of_way(self, vehicle_id: str, take: bool) -> None:
        self._api.vehicle.setSpeedMode(
            vehicle_id, TAKING_RIGHT_OF_WAY if take else DEFAULT_SPEED_MODE
        )

    def route_contexts(
        self, vehicle_ids: Sequence[str], horizons_m: Sequence[float], read_links: Sequence[bool]
    ) -> list[tuple[SignalAhead | None, VehicleAhead | None, LinkAhead | float | None]]:
        """For each vehicle: the next light, SUMO's leader and the link at the end of its
        lane, the last two within the vehicle's horizon (SUMO's view, read after the last
        step). Each vehicle's lane and position are read once. Where `read_links` is
        False the link is not read: its place holds the distance to the lane's end
        instead (`link_ahead` reads it)."""
        veh = self._api.vehicle
        self._tls_states.clear()  # this step's
        contexts = []
        positions = self._lane_positions
        for vid, horizon, read in zip(vehicle_ids, horizons_m, read_links, strict=True):
            lane = self._lane_now(vid)
            remaining = math.inf
            if lane:
                position = positions[vid] = veh.getLanePosition(vid)
                remaining = self._lane_length(lane) - position
            signal = self._next_signal(vid, lane, remaining)
            ahead = self.vehicle_ahead(vid, horizon)
            link: LinkAhead | float | None = None
            if lane and not lane.startswith(":") and remaining <= horizon:
                link = self.link_ahead(vid, remaining) if read else remaining
            contexts.append((signal, ahead, link))
        return contexts

    def _next_signal(self, vid: str, lane: str, remaining_m: float) -> SignalAhead | None:
        """SUMO's next light on the vehicle's route (`getNextTLS`, its first entry).

        SUMO walks the whole rest of the route for it (3 us a call on the bench's grid,
        where the routes pass 8.6 lights on average), so where the light is at the end of
        the vehicle's lane its link is kept while the vehicle stays on that lane; its
        distance is then SUMO's own expression (lane length - position) and its state the
        light's state at the link's index, read once per light and step."""
        if not lane:
            return None
        known = self._lane_signals.get(vid)
        if known is not None and known[0] == lane:
            _, tls_id, index = known
            states = self._tls_states.get(tls_id)
            if states is None:
                states = self._tls_states[tls_id] = str(
                    self._api.trafficlight.getRedYellowGreenState(tls_id)
                )
            return SignalAhead(tls_id, index, states[index], remaining_m)
        self._lane_signals.pop(vid, None)
        tls = self._api.vehicle.getNextTLS(vid)
        if not tls:
            return None
        tls_id, link_index, distance, state = tls[0]
        if distance == remaining_m:  # at the end of this lane
            self._lane_signals[vid] = (lane, str(tls_id), int(link_index))
        return SignalAhead(str(tls_id), int(link_index), str(state), float(distance))

    def link_ahead(self, vehicle_id: str, distance_m: float) -> LinkAhead | None:
        """The link at the end of the vehicle's lane, `distance_m` ahead (None at the
        route's end). SUMO's link query is the dearest of the per-vehicle reads (it walks
        every link left on the route: about 12 µs a query on the bench), so it is made only
        for a vehicle on a lane (not in a junction) whose end is within its horizon, and
        only where a stage or its controller needs the link (`route_contexts`)."""
        links = self._api.vehicle.getNextLinks(vehicle_id)
        if not links:
            return None
        _, has_prio, is_open, has_foe, _, state, _, _ = links[0]
        return LinkAhead(str(state), bool(has_prio), bool(is_open), bool(has_foe), distance_m)

    def _lane_edge(self, lane_id: str) -> str:
        edge = self._lane_edges.get(lane_id)
        if edge is None:
            edge = self._lane_edges[lane_id] = str(self._api.lane.getEdgeID(lane_id))
        return edge

    def _lane_length(self, lane_id: str) -> float:
        length = self._lane_lengths.get(lane_id)
        if length is None:
            length = self._lane_lengths[lane_id] = float(self._api.lane.getLength(lane_id))
        return length

    def _lane_now(self, vid: str) -> str:
        """The vehicle's lane as SUMO has it until its next step: from this step's world
        read where the vehicle is in it (SUMO lists a vehicle on the lane `getLaneID`
        gives, `snapshot`), else asked ('' for a vehicle on no lane)."""
        world = self._last_read
        if world is not None and (i := world.index.get(vid)) is not None:
            return world.lane_ids[i]
        return str(self._api.vehicle.getLaneID(vid))

    def _position_now(self, vid: str) -> float:
        """The vehicle's lane position as SUMO has it until its next step: the one
        `route_contexts` read this step, else asked."""
        known = self._lane_positions.get(vid)
        if known is None:
            return float(self._api.vehicle.getLanePosition(vid))
        return known

    def vehicle_ahead(self, vehicle_id: str, horizon_m: float) -> VehicleAhead | None:
        """The nearest vehicle ahead on the route's lanes within `horizon_m` (SUMO's view).
        None for one whose back is not ahead of the front bumper: SUMO's leader in the
        sublane model may be a car beside on a wide lane (the footprint check,
        `loop.obstacles`, sees any body in the way). Followed as a leader, it held a
        platoon car in a junction beside a car that had overtaken it on the right, in
        the way of that car's move back into the lane after (race circuit, seed 44)."""
        veh = self._api.vehicle
        found = veh.getLeader(vehicle_id, horizon_m)
        if not found or not found[0]:
            return None
        other = str(found[0])
        min_gap = self._min_gaps.get(vehicle_id)
        if min_gap is None:  # fixed by its type: read once
            min_gap = self._min_gaps[vehicle_id] = float(veh.getMinGap(vehicle_id))
        gap = float(found[1]) + min_gap  # getLeader's distance excludes the minGap
        if gap < 0.0:
            return None
        world = self._last_read
        if world is not None and (i := world.index.get(other)) is not None:
            return VehicleAhead(other, gap, float(world.speed_mps[i]))
        return VehicleAhead(other, gap, float(veh.getSpeed(other)))

    def sumo_collisions(self) -> Iterator[tuple[str, str, str]]:
        """Collisions SUMO itself detected this step: (collider, victim, type)."""
        for c in self._api.simulation.getCollisions():
            yield c.collider, c.victim, c.type


#: libsumo's static methods that only hand their arguments on to the compiled function
#: ``_libsumo.<domain>_<name>``: the loop calls these about 30 times per platoon vehicle
#: and step, and the Python frame of the static method is a third of a position read's
#: cost (0.46 against 0.30 µs, docs/performance.md). `tests/test_libsumo_direct.py`
#: checks that each still only passes its arguments on.
PASS_THROUGH = {
    "vehicle": (
        "getPosition", "getSpeed", "getAngle", "getLaneID", "getLanePosition", "setSpeed",
        "changeLane", "getNextLinks", "getWaitingTime", "getLength", "getWidth", "getTypeID",
        "getLateralLanePosition", "getNextTLS", "moveToXY", "setPreviousSpeed",
        "changeSublane", "setMaxSpeedLat", "getLateralSpeed", "getLaneChangeState",
        "getBestLanes",
    ),
    "lane": ("getLastStepVehicleIDs", "getWidth", "getShape", "getLength"),
    "trafficlight": ("getRedYellowGreenState",),
}  # fmt: skip


class _Libsumo:
    """The libsumo module with the `PASS_THROUGH` methods of its domains bound to the
    compiled functions they call (the same functions, one Python frame less), when the
    backend is made: a test that patches one of those must patch `libsumo._libsumo`."""

    def __init__(self) -> None:
        for domain, names in PASS_THROUGH.items():
            direct = _LibsumoDomain(getattr(libsumo, domain))
            for name in names:
                setattr(direct, name, getattr(libsumo._libsumo, f"{domain}_{name}"))
            setattr(self, domain, direct)

    def __getattr__(self, name: str) -> Any:
        return getattr(libsumo, name)


class _LibsumoDomain:
    """One libsumo domain (``libsumo.vehicle`` ...); what `_Libsumo` did not bind comes
    from it."""

    def __init__(self, domain: object):
        self._domain = domain

    def __getattr__(self, name: str) -> Any:
        return getattr(self._domain, name)


class _GuiConnection:
    """The `traci` client with a lost connection (sumo-gui's window closed) reported as
    a SumoError, whichever call meets it: one line for the user, not a traceback."""

    def __init__(self, target: object):
        self._target = target

    def __getattr__(self, name: str) -> Any:
        value = getattr(self._target, name)
        if isinstance(value, (type, int, float, str)):  # exception classes, constants
            return value
        if callable(value):
            return functools.partial(_guarded_call, value)
        return _GuiConnection(value)  # a domain (vehicle, lane, ...) or a module


def _guarded_call(function: Any, *args: Any, **kwargs: Any) -> Any:
    import traci

    try:
        return function(*args, **kwargs)
    except traci.FatalTraCIError as exc:
        raise SumoError(f"sumo-gui closed the connection ({exc}); the run stops") from None


def resolve_sumo_path(value: str) -> Path:
    """`sumo:<path>` names a file shipped inside the eclipse-sumo package."""
    if value.startswith("sumo:"):
        return Path(sumo.SUMO_HOME) / value[len("sumo:") :]
    return Path(value)


def _points(pairs: Iterable[tuple[float, float]], n: int) -> NDArray[np.float64]:
    """`n` pairs as an (n, 2) array (without the per-pair cost of `np.array`)."""
    return np.fromiter(itertools.chain.from_iterable(pairs), np.float64, 2 * n).reshape(n, 2)


def _empty_world(time_s: float) -> WorldSnapshot:
    none = np.empty(0)
    return WorldSnapshot(time_s, (), none, none, none, none, none, none, (), {})


#: Smallest cell of the lane grid [m] (larger where the network would need more than
#: `_LANE_GRID_CELLS` of them).
_LANE_CELL_M = 50.0
_LANE_GRID_CELLS = 1 << 20
#: A vehicle's front bumper lies within half its lane's width of the lane's shape; this
#: much more is allowed for shapes' corners and SUMO's rounding [m].
_LANE_SHAPE_TOLERANCE_M = 1.0


@dataclass(frozen=True)
class _LaneGrid:
    """Every lane's shape segments, listed in the square cells their bounding boxes
    (widened by half the lane width) touch, for "lanes near these points" without
    scanning the network: `near` tests each segment of the cells around a point
    exactly (`lanes_within`), so a lane is listed only where a vehicle on it could be
    within the radius, not because it shares a cell with one."""

    lane_ids: NDArray[np.object_]
    origin: NDArray[np.float64]
    cell_m: float
    cells_y: int
    cell_starts: NDArray[np.int64]
    cell_segments: NDArray[np.int64]
    segments: NDArray[np.float64]
    """(ax, ay, bx, by) of each segment."""
    pads: NDArray[np.float64]
    """Half the segment's lane width plus `_LANE_SHAPE_TOLERANCE_M` [m]."""
    segment_lane: NDArray[np.int64]
    lane_classes: tuple[frozenset[str], ...]
    """The vehicle classes each lane allows, as the network defines them (permissions
    changed during the run, by a rerouter or a plug-in, are not seen)."""

    @classmethod
    def build(cls, api: _Libsumo | _GuiConnection, cell_m: float) -> _LaneGrid:
        lane_ids = sorted(api.lane.getIDList())
        segments, pads, owners = [], [], []
        for k, lane in enumerate(lane_ids):
            shape = np.asarray(api.lane.getShape(lane), dtype=np.float64).reshape(-1, 2)
            if len(shape) == 1:  # a point: a segment of no length
                shape = np.concatenate([shape, shape])
            segments.append(np.hstack([shape[:-1], shape[1:]]))
            pads.append(np.full(max(len(shape) - 1, 0), 0.5 * float(api.lane.getWidth(lane))))
            owners.append(np.full(max(len(shape) - 1, 0), k, dtype=np.int64))
        seg = np.concatenate(segments) if segments else np.zeros((0, 4))
        pad = np.concatenate(pads) + _LANE_SHAPE_TOLERANCE_M if pads else np.zeros(0)
        lo = np.minimum(seg[:, :2], seg[:, 2:]) - pad[:, None]
        hi = np.maximum(seg[:, :2], seg[:, 2:]) + pad[:, None]
        origin = lo.min(axis=0) if len(seg) else np.zeros(2)
        extent = (hi.max(axis=0) - origin) if len(seg) else np.ones(2)
        cell_m = max(cell_m, math.sqrt(float(extent[0] * extent[1]) / _LANE_GRID_CELLS))
        cells_x, cells_y = np.maximum(np.floor(extent / cell_m).astype(np.int64) + 1, 1).tolist()
        first = np.floor((lo - origin) / cell_m).astype(np.int64)
        last = np.floor((hi - origin) / cell_m).astype(np.int64)
        cells, listed = [], []
        for s, ((x0, y0), (x1, y1)) in enumerate(zip(first.tolist(), last.tolist(), strict=True)):
            for cx in range(x0, x1 + 1):
                for cy in range(y0, y1 + 1):
                    cells.append(cx * cells_y + cy)
                    listed.append(s)
        by_cell = np.asarray(cells, dtype=np.int64)
        order = np.argsort(by_cell, kind="stable")
        counts = np.bincount(by_cell, minlength=cells_x * cells_y)
        return cls(
            lane_ids=np.array(lane_ids, dtype=object),
            origin=origin,
            cell_m=cell_m,
            cells_y=cells_y,
            cell_starts=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            cell_segments=np.asarray(listed, dtype=np.int64)[order],
            segments=np.ascontiguousarray(seg),
            pads=pad,
            segment_lane=np.concatenate(owners) if owners else np.zeros(0, dtype=np.int64),
            lane_classes=tuple(frozenset(api.lane.getAllowed(lane)) for lane in lane_ids),
        )

    def listable(self, classes: frozenset[str]) -> NDArray[np.bool_]:
        """Which lanes allow one of these vehicle classes (a lane listing none allows
        every class; a vehicle of SUMO's class `ignoring` may use any lane)."""
        if "ignoring" in classes:
            return np.ones(len(self.lane_classes), dtype=np.bool_)
        return np.array(
            [not allowed or not allowed.isdisjoint(classes) for allowed in self.lane_classes],
            dtype=np.bool_,
        )

    def near(
        self, points: NDArray[np.float64], radius_m: float, listable: NDArray[np.bool_]
    ) -> list[str]:
        """In the order of `lane_ids` (on the bench's grid about 470 lanes a step near 100
        platoon cars, where the cells around them held 564)."""
        mask = lanes_within(
            points, radius_m, self.origin, self.cell_m, self.cells_y, self.cell_starts,
            self.cell_segments, self.segments, self.pads, self.segment_lane, len(self.lane_ids),
        )  # fmt: skip
        listed: list[str] = self.lane_ids[mask & listable].tolist()
        return listed
