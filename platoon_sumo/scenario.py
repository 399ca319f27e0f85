"""Scenario files: YAML -> frozen dataclasses -> a checked, resolved run plan.

`load_scenario` checks the file's shape (keys, types, ranges); `prepare` checks it
against the world (files exist, edges exist, routes connect, platoons fit, controllers
and their parameters are known). Both raise ScenarioError naming file and key path.
Relative paths in a scenario are relative to the scenario file; `sumo:<path>` points
inside the installed eclipse-sumo package (e.g. `sumo:tools/game/DRT/osm.net.xml`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from platoon_sumo.actuation import ACTUATORS
from platoon_sumo.config_loader import (
    FieldError,
    bounded,
    check_bounds,
    load_dataclass,
    require,
    require_choice,
    require_positive,
)
from platoon_sumo.control import CONTROLLERS, Controller
from platoon_sumo.control.base import SumoCarFollowing, sumo_car_following
from platoon_sumo.errors import ScenarioError, did_you_mean
from platoon_sumo.sensors import laser_sensor as _laser_sensor  # noqa: F401 (registers)
from platoon_sumo.sensors import radar as _radar  # noqa: F401 (registers)
from platoon_sumo.sensors import v2v as _v2v  # noqa: F401 (registers)
from platoon_sumo.sensors.base import SENSORS, SensorModel
from platoon_sumo.sensors.laser import LASER_PRESETS, LaserConfig
from platoon_sumo.sumo.backend import resolve_sumo_path
from platoon_sumo.sumo.inputs import InputFileError, check_route_file, check_xml
from platoon_sumo.sumo.network import Network, RouteError
from platoon_sumo.supervisor import SupervisorConfig
from platoon_sumo.vehicles import VEHICLE_MODELS, MotionLimits, Powertrain, VehicleModel
from platoon_sumo.yaml_input import read_mapping

VEHICLE_CLASSES = (
    "ignoring", "private", "emergency", "authority", "army", "vip", "pedestrian", "passenger",
    "hov", "taxi", "bus", "coach", "delivery", "truck", "trailer", "motorcycle", "moped",
    "bicycle", "evehicle", "tram", "rail_urban", "rail", "rail_electric", "rail_fast", "ship",
    "container", "cable_car", "subway", "aircraft", "wheelchair", "scooter", "drone",
    "custom1", "custom2",
)  # fmt: skip
LANE_CHANGE_MODELS = ("LC2013", "SL2015", "DK2008")

# Ranges of numeric keys (also printed in docs/scenarios.md).
#: Shortest step SUMO accepts (it counts time in milliseconds) [s].
MIN_STEP_S = 0.001
#: Latest time of any kind (begin, end, departures, horizons): about 116 days [s].
MAX_TIME_S = 10_000_000.0
#: SUMO's seeds are 32-bit signed integers.
MAX_SEED = 2**31 - 1
#: Physically meaningful vehicles: speed [m/s], length and width [m], acceleration [m/s²].
MAX_SPEED_MPS = 150.0
MAX_LENGTH_M = 50.0
MAX_WIDTH_M = 20.0
MAX_ACCEL_MPS2 = 50.0
#: Demand: a flow's rate [vehicles/h], random trips' shortest period [s] and most
#: departures one random-trips section may ask for.
MAX_VEHS_PER_HOUR = 100_000.0
MIN_PERIOD_S = 0.01
MAX_RANDOM_TRIPS = 2_000_000
#: Platoons one flow's `platoon_share` may insert over its span.
MAX_FLOW_PLATOONS = 100_000

#: Names that become file or folder names (scenario name, platoon, vehicle type and sensor
#: ids): a letter or digit, then letters, digits, `_`, `.` or `-`, at most 64 characters.
SAFE_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
SAFE_ID_TEXT = "1 to 64 letters, digits, '_', '.' or '-', starting with a letter or digit"


def require_safe_id(value: str, key: str) -> None:
    """`value` must be usable as a file name anywhere (see SAFE_ID)."""
    ok = SAFE_ID.fullmatch(value) is not None
    require(ok, key, f"{value!r} is not a safe name: use {SAFE_ID_TEXT}")


CAR_FOLLOW_MODELS = (
    "Krauss", "KraussOrig1", "KraussPS", "KraussX", "EIDM", "IDM", "IDMM", "IIDM", "ACC",
    "CACC", "W99", "Wiedemann", "SmartSK", "Daniel1", "PWagner2009", "BKerner", "Rail", "CC",
)  # fmt: skip


@dataclass(frozen=True)
class SimulationConfig:
    step_s: float = bounded(0.1, ge=MIN_STEP_S, le=1.0)
    """SUMO step length and control period [s]."""
    end_s: float = bounded(600.0, gt=0, le=MAX_TIME_S)
    """Simulated time at which the run stops [s]."""
    begin_s: float = bounded(0.0, ge=0, le=MAX_TIME_S)
    """Simulated time at which SUMO starts [s]."""
    seed: int = bounded(42, ge=0, le=MAX_SEED)
    """Seeds SUMO and every random generator of ours."""
    lateral_resolution_m: float | None = bounded(0.8, gt=0, le=10)
    """SUMO sublane resolution [m]: planar and sublane platoons need it (without it
    their poses snap to lane centres and SUMO drivers miss a car between lanes). null: no
    sublane model, SUMO's lane changes take one step (enough when every platoon uses
    `actuation: lane`)."""
    time_to_teleport_s: float | None = bounded(None, gt=0, le=MAX_TIME_S)
    """SUMO's jam teleport: a vehicle stuck this long [s] is moved ahead along its route
    (`--time-to-teleport`); each teleport is a `teleport` event. null (default): off,
    vehicles wait (a gridlock stays one)."""

    def __post_init__(self) -> None:
        require(math.isfinite(self.begin_s), "begin_s", "must be a finite number")
        require(math.isfinite(self.step_s), "step_s", "must be a finite number")
        require(math.isfinite(self.end_s), "end_s", "must be a finite number")
        require(self.step_s > 0, "step_s", f"must be > 0 s, got {self.step_s}")
        require(self.step_s <= 1.0, "step_s", f"must be <= 1 s, got {self.step_s}")
        require(self.end_s > self.begin_s, "end_s", "must be after begin_s")
        require(self.seed >= 0, "seed", "must be >= 0")
        require(
            self.lateral_resolution_m is None or self.lateral_resolution_m > 0,
            "lateral_resolution_m",
            "must be > 0 (or null: no sublane model)",
        )
        require(
            self.time_to_teleport_s is None
            or (math.isfinite(self.time_to_teleport_s) and self.time_to_teleport_s > 0),
            "time_to_teleport_s",
            "must be a finite number > 0 s (or null: no teleports)",
        )
        check_bounds(self)  # here too: `run --end/--seed` replace fields after loading


@dataclass(frozen=True)
class NetworkConfig:
    net_file: str | None = None
    """A .net.xml (relative to the scenario file, or `sumo:<path in eclipse-sumo>`)."""
    sumocfg: str | None = None
    """A .sumocfg: its net, route and additional files are used."""
    route_files: tuple[str, ...] = ()
    """SUMO route files (`.rou.xml`) loaded with the network."""
    additional_files: tuple[str, ...] = ()
    """Polygons of type `wall` or `building*` in these files are obstacles for lasers."""
    kerbs: bool = False
    """Make the boundary of the road area (lanes + junctions) a laser obstacle."""
    kerb_margin_m: float = bounded(0.2, ge=0, le=10)
    """Distance of the kerb line outside the outermost lane edge."""

    def __post_init__(self) -> None:
        require(self.kerb_margin_m >= 0, "kerb_margin_m", "must be >= 0")
        require(
            (self.net_file is None) != (self.sumocfg is None),
            "net_file",
            "give exactly one of network.net_file and network.sumocfg",
        )


@dataclass(frozen=True)
class VehicleTypeConfig:
    """A SUMO vehicle type for human-driven traffic, with its driver model."""

    id: str
    """Type id; `traffic.flows[].type` refers to it."""
    car_follow_model: str = "Krauss"
    """SUMO car-following model (list below)."""
    probability: float = bounded(1.0, gt=0, le=1e6)
    """Share of this type in the background mix."""
    vclass: str = "passenger"
    """SUMO vehicle class; decides which lanes the type may use."""
    length_m: float = bounded(5.0, gt=0, le=MAX_LENGTH_M)
    """Length, bumper to bumper [m]."""
    width_m: float = bounded(1.8, gt=0, le=MAX_WIDTH_M)
    """Width [m]."""
    min_gap_m: float = bounded(2.5, ge=0, le=100)
    """Gap kept to the vehicle ahead when stopped [m]."""
    max_speed_mps: float = bounded(55.0, gt=0, le=MAX_SPEED_MPS)
    """Top speed [m/s]."""
    accel_mps2: float = bounded(2.6, gt=0, le=MAX_ACCEL_MPS2)
    """Maximum acceleration [m/s²]."""
    decel_mps2: float = bounded(4.5, gt=0, le=MAX_ACCEL_MPS2)
    """Comfortable deceleration [m/s²]."""
    emergency_decel_mps2: float = bounded(9.0, gt=0, le=MAX_ACCEL_MPS2)
    """Deceleration in an emergency [m/s²]."""
    sigma: float = bounded(0.5, ge=0, le=1)
    """Driver imperfection (Krauss family)."""
    tau_s: float = bounded(1.0, gt=0, le=100)
    """Desired time headway."""
    speed_factor: float = bounded(1.0, gt=0, le=10)
    """Mean multiplier on lane speed limits (SUMO speedFactor)."""
    speed_dev: float = bounded(0.1, ge=0, le=10)
    """Spread of the speed factor between drivers (SUMO speedDev)."""
    lane_change_model: str = "SL2015"
    """SUMO lane-change model."""
    params: Mapping[str, Any] = field(default_factory=dict)
    """Further attributes written as-is onto the vType (e.g. `delta` for IDM)."""

    def __post_init__(self) -> None:
        require_safe_id(self.id, "id")
        require_choice(self.car_follow_model, CAR_FOLLOW_MODELS, "car_follow_model")
        require_choice(self.lane_change_model, LANE_CHANGE_MODELS, "lane_change_model")
        require_choice(self.vclass, VEHICLE_CLASSES, "vclass")
        require_positive(
            self, "length_m", "width_m", "max_speed_mps", "accel_mps2", "decel_mps2", "tau_s"
        )
        require(self.min_gap_m >= 0, "min_gap_m", "must be >= 0")
        require(self.probability > 0, "probability", "must be > 0")
        require(0 <= self.sigma <= 1, "sigma", "must be in [0, 1]")
        require(
            self.emergency_decel_mps2 >= self.decel_mps2,
            "emergency_decel_mps2",
            "must be >= decel_mps2",
        )


@dataclass(frozen=True)
class FlowConfig:
    from_edge: str
    """First edge of the flow's route."""
    to_edge: str
    """Last edge of the flow's route."""
    vehs_per_hour: float = bounded(gt=0, le=MAX_VEHS_PER_HOUR)
    """Vehicles an hour."""
    via_edges: tuple[str, ...] = ()
    """Edges the route must pass, in order."""
    begin_s: float = bounded(0.0, ge=0, le=MAX_TIME_S)
    """Start of the flow [s]."""
    end_s: float | None = bounded(None, gt=0, le=MAX_TIME_S)
    """Defaults to the simulation's end."""
    type: str | None = None
    """A vehicle type id; defaults to the background mix of `traffic.vehicle_types`."""
    platoon_share: float = bounded(0.0, ge=0, lt=1)
    """Penetration: share of this flow's vehicles that drive as platoons instead, built
    from `platoon_template` and inserted evenly over the flow's time span."""
    platoon_template: str | None = None
    """Id of a platoon with `template: true` giving members, vehicle and controllers."""

    def __post_init__(self) -> None:
        require(self.vehs_per_hour > 0, "vehs_per_hour", "must be > 0")
        require(0 <= self.platoon_share < 1, "platoon_share", "must be in [0, 1)")
        require(
            self.platoon_share == 0 or self.platoon_template is not None,
            "platoon_template",
            "a flow with platoon_share > 0 needs the id of a template platoon",
        )
        require(self.end_s is None or self.end_s > self.begin_s, "end_s", "must be after begin_s")


@dataclass(frozen=True)
class RandomTripsConfig:
    """Random trips generated at run time with SUMO's randomTrips.py, routed by SUMO."""

    period_s: float = bounded(ge=MIN_PERIOD_S, le=MAX_TIME_S)
    """Mean time between two departures [s] (e.g. 0.5 = 7,200 vehicles an hour)."""
    begin_s: float = bounded(0.0, ge=0, le=MAX_TIME_S)
    """Time of the first departure [s]."""
    end_s: float | None = bounded(None, gt=0, le=MAX_TIME_S)
    """End of the departures [s]; default: the simulation's end."""
    seed: int | None = bounded(None, ge=0, le=MAX_SEED)
    """Defaults to the simulation seed."""
    min_distance_m: float = bounded(300.0, ge=0, le=1e6)
    """Shortest distance between a trip's start and end [m]."""
    fringe_factor: float = bounded(5.0, ge=1, le=1e6)
    """How much more likely trips start/end at the network border than inside."""

    def __post_init__(self) -> None:
        require(self.period_s > 0, "period_s", "must be > 0")
        require(self.min_distance_m >= 0, "min_distance_m", "must be >= 0")
        require(self.fringe_factor >= 1, "fringe_factor", "must be >= 1")


@dataclass(frozen=True)
class TrafficConfig:
    vehicle_types: tuple[VehicleTypeConfig, ...] = ()
    """Vehicle types of the human-driven traffic; flows and random trips without a `type`
    draw from them by `probability`."""
    route_files: tuple[str, ...] = ()
    """SUMO route files (`.rou.xml`) of human-driven traffic."""
    flows: tuple[FlowConfig, ...] = ()
    """Flows of human-driven vehicles between two edges, routed by SUMO."""
    random_trips: RandomTripsConfig | None = None
    """Random trips all over the network (null: none)."""
    scale: float = bounded(1.0, gt=0, le=100)
    """Multiplies all human-driven demand (route files, flows, random trips): SUMO's
    `--scale`, e.g. 0.5 keeps every second vehicle. Platoons are not scaled."""

    def __post_init__(self) -> None:
        require_positive(self, "scale")
        ids = [t.id for t in self.vehicle_types]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        require(
            not duplicates,
            "vehicle_types",
            f"duplicate vehicle type id(s): {', '.join(duplicates)}",
        )


@dataclass(frozen=True)
class RouteConfig:
    edges: tuple[str, ...] = ()
    """The route as the full list of connected edges."""
    from_edge: str | None = None
    """Start edge; the fastest route to `to_edge` is computed."""
    to_edge: str | None = None
    """Destination edge (with `from_edge`)."""
    via_edges: tuple[str, ...] = ()
    """Edges the computed route must pass, in order."""

    def __post_init__(self) -> None:
        require(
            bool(self.edges) != (self.from_edge is not None),
            "edges",
            "give either route.edges or route.from_edge + route.to_edge",
        )
        require(
            (self.from_edge is None) == (self.to_edge is None),
            "to_edge",
            "from_edge and to_edge go together",
        )


@dataclass(frozen=True)
class VehicleConfig:
    """Geometry and limits of the platoon's vehicles (all members alike)."""

    model: str = "bicycle"
    """A registered vehicle model: bicycle (cars) or unicycle (differential-drive robots)."""
    length_m: float = bounded(4.5, gt=0, le=MAX_LENGTH_M)
    """Length, bumper to bumper [m]."""
    width_m: float = bounded(1.8, gt=0, le=MAX_WIDTH_M)
    """Width [m]."""
    min_gap_m: float = bounded(2.5, ge=0, le=100)
    """What SUMO drivers keep behind this vehicle when stopped."""
    wheelbase_m: float = bounded(2.7, gt=0, le=MAX_LENGTH_M)
    """Rear axle to front axle [m] (bicycle model)."""
    rear_overhang_m: float | None = bounded(None, ge=0, le=MAX_LENGTH_M)
    """Rear bumper to reference point (rear axle); default centres the wheelbase."""
    max_speed_mps: float = bounded(16.7, gt=0, le=MAX_SPEED_MPS)
    """Top speed [m/s]."""
    max_accel_mps2: float = bounded(2.5, gt=0, le=MAX_ACCEL_MPS2)
    """Maximum acceleration [m/s²]."""
    max_decel_mps2: float = bounded(7.5, gt=0, le=MAX_ACCEL_MPS2)
    """Maximum braking deceleration [m/s²]."""
    max_yaw_rate_radps: float = bounded(1.0, gt=0, le=50)
    """Largest yaw rate [rad/s]."""
    max_steer_rad: float = bounded(0.6, gt=0, lt=math.pi / 2)
    """Front-wheel steering limit [rad] (bicycle model)."""
    vclass: str = "passenger"
    """SUMO vehicle class of the platoon's vehicle type."""
    sumo_tau_s: float = bounded(1.0, gt=0, le=100)
    """SUMO's driver time headway (tau) for the platoon's vehicle type [s]; matters with
    `actuation: lane` only, where SUMO's safe speed, computed with it, caps the command
    (smaller: SUMO lets the vehicle follow closer)."""
    sumo_speed_factor: float | None = bounded(1.0, gt=0, le=10)
    """Every member's SUMO speedFactor, without spread: with `actuation: lane` SUMO caps
    the speed command at this factor times the lane's speed limit (1.0: exactly the
    limit), the same for every member, so a follower is not held below the speed its
    predecessor drives. null: SUMO's default type, a factor drawn per vehicle (mean 1,
    deviation 0.1), as for its human drivers, so members' caps differ (on the A10 a
    last member drawn 1.007 fell 20 s behind its platoon and out of its laser's view)."""
    actuator_lag_s: float | None = bounded(None, ge=0, le=10)
    """First-order lag between the commanded and the achieved acceleration [s] (engine
    and brakes; Plexe's engine lag, 0.5 s by default there); 0: none. null: the vehicle
    model's default: 0.1 s for a bicycle (cars), none for a unicycle (the paper's robots)."""
    max_jerk_mps3: float | None = bounded(None, gt=0, le=10_000)
    """Largest change of the achieved acceleration per second [m/s³]; null: unbounded."""

    def __post_init__(self) -> None:
        require_choice(self.model, VEHICLE_MODELS.names(), "model")
        require_choice(self.vclass, VEHICLE_CLASSES, "vclass")
        require_positive(
            self,
            "length_m",
            "width_m",
            "wheelbase_m",
            "max_speed_mps",
            "max_accel_mps2",
            "max_decel_mps2",
            "max_yaw_rate_radps",
            "sumo_tau_s",
        )
        require(self.min_gap_m >= 0, "min_gap_m", "must be >= 0")
        require(0 < self.max_steer_rad < math.pi / 2, "max_steer_rad", "must be in (0, pi/2)")
        require(
            self.rear_overhang_m is None or 0 <= self.rear_overhang_m < self.length_m,
            "rear_overhang_m",
            "must be in [0, length_m)",
        )

    @property
    def front_offset_m(self) -> float:
        """Reference point (rear axle / wheel axle) to front bumper, along the heading."""
        if self.rear_overhang_m is not None:
            return self.length_m - self.rear_overhang_m
        if self.model == "unicycle":
            return self.length_m / 2
        return self.length_m - max(self.length_m - self.wheelbase_m, 0.0) / 2

    def powertrain(self) -> Powertrain:
        """The lag and jerk bound in effect: `actuator_lag_s`, or the model's default."""
        lag = self.actuator_lag_s
        if lag is None:
            lag = VEHICLE_MODELS.get(self.model).default_actuator_lag_s
        return Powertrain(lag, self.max_jerk_mps3)

    def limits(self) -> MotionLimits:
        return MotionLimits(
            max_speed_mps=self.max_speed_mps,
            max_accel_mps2=self.max_accel_mps2,
            max_decel_mps2=self.max_decel_mps2,
            max_yaw_rate_radps=self.max_yaw_rate_radps,
            max_steer_rad=self.max_steer_rad,
            wheelbase_m=self.wheelbase_m,
        )


@dataclass(frozen=True)
class SensorConfig:
    """A laser scanner: a preset name, optionally with fields overridden."""

    preset: str = "utm30lx"
    """A laser preset (see Laser presets below)."""
    overrides: Mapping[str, float | int] = field(default_factory=dict)
    """Laser fields replacing the preset's (see Laser presets below)."""

    def __post_init__(self) -> None:
        require_choice(self.preset, sorted(LASER_PRESETS), "preset")


@dataclass(frozen=True)
class SensorSpec:
    """A sensor model by name, with its parameters."""

    type: str
    """A registered sensor model or `package.module:Class`."""
    name: str | None = None
    """Key of its messages in the controller's `observation.sensors`; default: `type`."""
    params: Mapping[str, Any] = field(default_factory=dict)
    """The model's parameters (its Params dataclass)."""

    def __post_init__(self) -> None:
        if self.name is not None:
            require_safe_id(self.name, "name")


@dataclass(frozen=True)
class RoleConfig:
    """How a platoon member of one role (leader / follower) decides and senses."""

    type: str = "route_following"
    """A registered controller name or `package.module:Class`."""
    params: Mapping[str, Any] = field(default_factory=dict)
    """The controller's parameters (its Params dataclass; see the controller tables)."""
    sensor: SensorConfig | None = None
    """Laser scanner of the members in this role; null: no scan in their observations."""
    sensors: tuple[SensorSpec, ...] = ()
    """Further sensors (registered sensor models or `package.module:Class`), each
    delivered to the controller as `observation.sensors[name]`."""


@dataclass(frozen=True)
class PlatoonConfig:
    id: str
    """Platoon name; its vehicles are `<id>.0` (leader), `<id>.1`, ..."""
    route: RouteConfig | None = None
    """The route every member drives (required unless the platoon is a template)."""
    members: int = bounded(1, ge=1, le=100)
    """Number of vehicles (1 to 100); member 0 leads."""
    depart_s: float = bounded(0.0, ge=0, le=MAX_TIME_S)
    """When the platoon is handed to SUMO for insertion [s]."""
    spacing_m: float = bounded(8.0, gt=0, le=1000)
    """Initial bumper-to-bumper gap between members [m]."""
    depart_pos_m: float | None = bounded(None, gt=0, le=1e6)
    """Leader's front bumper on the first edge [m]; default: just room for everyone (or
    2 m before the edge's end). Members that do not fit behind it depart one by one, in order, as
    the ones ahead leave room."""
    depart_lane: int | None = bounded(None, ge=0, le=100)
    """Lane index on the first edge (0 = rightmost); default 0."""
    vehicle: VehicleConfig = VehicleConfig()
    """Geometry, motion model and limits of the members."""
    actuation: str | None = None
    """How commands reach SUMO; null: the vehicle model's default (`sublane` for the
    bicycle, cars; `planar` for the unicycle, robots). `planar`: the vehicle model
    integrates speed and heading and the pose is placed into SUMO (free lateral motion:
    robots, the paper's world, our own lane changes). `lane`: SUMO drives the vehicle
    along its lanes (lane keeping, the route's lane changes, its safe speed at junctions
    and lights as the last safety layer) at the speed the controller and supervisor
    command; heading is SUMO's.
    `sublane`: SUMO drives the speed as in `lane`, and the controller's heading moves the
    car sideways within and across lanes through SUMO's sublane model (needs
    `simulation.lateral_resolution_m`); SUMO makes no lane change of its own, except the
    route's change for a car standing or crawling on a lane its route leaves. A plug-in's
    `package.module:Class` (an actuator registered in `platoon_sumo.actuation.ACTUATORS`'s
    shape) is accepted too."""
    split_gap_m: float = bounded(60.0, gt=0, le=10_000)
    """Without a laser, a follower farther than this from its predecessor counts as split
    from it (with a laser: when the predecessor is out of its scan) [m]."""
    supervisor: SupervisorConfig = field(default_factory=SupervisorConfig)
    """Traffic rules and last-resort braking applied to every member's commands."""
    leader: RoleConfig = RoleConfig()
    """Controller of member 0."""
    follower: RoleConfig = RoleConfig()
    """Controller of members 1 and up."""

    template: bool = False
    """Only a template for flows with `platoon_share` (it does not drive itself)."""

    def __post_init__(self) -> None:
        require(self.route is not None or self.template, "route", "required key is missing")
        require(
            bool(self.id) and " " not in self.id and "." not in self.id,
            "id", "must be a non-empty name without spaces or dots",
        )  # fmt: skip
        require_safe_id(self.id, "id")
        if self.actuation is None:
            try:
                model: object = VEHICLE_MODELS.get(self.vehicle.model)
            except LookupError:
                model = None  # the vehicle's own check names an unknown model
            default = getattr(model, "default_actuation", None) or "planar"
            object.__setattr__(self, "actuation", default)
        try:  # a registered name, or a plug-in's `package.module:Class`
            ACTUATORS.get(self.actuation_name)
        except LookupError as exc:
            raise FieldError("actuation", str(exc)) from None
        require(self.members >= 1, "members", "must be >= 1")
        require(self.members <= 100, "members", "must be <= 100")
        require(self.spacing_m > 0, "spacing_m", "must be > 0")
        require(self.depart_s >= 0, "depart_s", "must be >= 0")

    def member_ids(self) -> list[str]:
        return [f"{self.id}.{k}" for k in range(self.members)]

    @property
    def actuation_name(self) -> str:
        """The actuation in effect (`actuation`, or the vehicle model's default)."""
        assert self.actuation is not None  # resolved in __post_init__
        return self.actuation


@dataclass(frozen=True)
class OutputConfig:
    directory: str | None = None
    """Results folder (relative to the working directory); default `results/<name>`."""
    trajectories: bool = True
    """Per-step table of the platoon vehicles (trajectories.csv)."""
    tripinfo: bool = True
    """SUMO's tripinfo of every vehicle (tripinfo.csv)."""
    chunk_rows: int = bounded(20_000, ge=1, le=10_000_000)
    """Rows buffered before the trajectory table is appended to disk."""
    format: str = "csv"
    """Format of the trajectory table: `csv`, or `parquet`."""
    metrics_start_s: float = bounded(0.0, ge=0, le=MAX_TIME_S)
    """Spacing, comfort and string-stability metrics use the steps from this simulation
    time on (e.g. after a warm-up); safety events always count over the whole run [s]."""
    sumo_outputs: bool = True
    """SUMO's emissions device in tripinfo, its summary output and edgeData (network
    effect on the other traffic)."""
    edgedata_period_s: float = bounded(60.0, gt=0, le=MAX_TIME_S)
    """Aggregation interval of SUMO's edgeData output [s]."""
    scan_snapshot_s: float | None = bounded(None, ge=0, le=MAX_TIME_S)
    """Keep the first follower's laser scan at this time for the report's scan figure;
    default: the scan halfway through its scans that saw its predecessor [s]."""
    scene_period_s: float | None = bounded(0.5, gt=0, le=MAX_TIME_S)
    """Every this long (rounded to whole steps), the vehicles near the platoons and the
    platoon lasers' latest scans go to `scene.csv` and `scans.npz`, which
    `platoon-sumo animate` draws [s]; null: no scene files."""
    scene_radius_m: float = bounded(60.0, gt=0, le=10_000)
    """The scene keeps the vehicles whose front bumper is within this distance of a
    platoon vehicle's (at most those the loop reads: within the sensors' reach) [m]."""
    gridlock_after_s: float | None = bounded(300.0, gt=0, le=MAX_TIME_S)
    """A vehicle (any, SUMO's or ours) standing still this long, neither at a stop of its
    schedule nor queued within 250 m of a red light, is reported as gridlocked (a
    `gridlock` event; checked every 10 simulated seconds) [s]; null: no check."""

    def __post_init__(self) -> None:
        require(self.chunk_rows >= 1, "chunk_rows", "must be >= 1")
        require(
            self.gridlock_after_s is None
            or (math.isfinite(self.gridlock_after_s) and self.gridlock_after_s > 0),
            "gridlock_after_s",
            "must be a finite number > 0 s (or null: no check)",
        )
        require_choice(self.format, ("csv", "parquet"), "format")
        require(math.isfinite(self.metrics_start_s), "metrics_start_s", "must be finite")
        require(self.edgedata_period_s > 0, "edgedata_period_s", "must be > 0")


@dataclass(frozen=True)
class Scenario:
    name: str
    """Run name: the default results folder is `results/<name>`."""
    simulation: SimulationConfig = SimulationConfig()
    network: NetworkConfig = NetworkConfig(net_file="")
    traffic: TrafficConfig = TrafficConfig()
    platoons: tuple[PlatoonConfig, ...] = ()
    outputs: OutputConfig = OutputConfig()
    description: str = ""
    """Free text for people; the run does not use it."""

    def __post_init__(self) -> None:
        require_safe_id(self.name, "name")
        ids = [p.id for p in self.platoons]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        require(not duplicates, "platoons", f"duplicate platoon id(s): {', '.join(duplicates)}")


# --------------------------------------------------------------------------- loading


@dataclass(frozen=True)
class ScenarioSource:
    """A scenario with where it came from (for relative paths, messages and the hash)."""

    scenario: Scenario
    path: Path
    text: str

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()

    def reproducible_yaml(self, simulation: SimulationConfig) -> str:
        """The scenario as run: effective seed and times, file paths made absolute, so the
        copy in a results folder repeats the run from anywhere."""
        data = dict(yaml.safe_load(self.text))
        data.setdefault("name", self.scenario.name)
        if not self.scenario.platoons:  # e.g. run with --no-platoons
            data.pop("platoons", None)
        entries = data.get("platoons") or []
        if len(entries) == len(self.scenario.platoons):
            for entry, platoon in zip(entries, self.scenario.platoons, strict=True):
                if isinstance(entry, dict) and entry.get("actuation") is None:
                    # the default in effect, so the copy repeats it whatever the defaults
                    # of a later version (cars: planar until 2026-11-26, then sublane)
                    entry["actuation"] = platoon.actuation_name
        data["simulation"] = {**(data.get("simulation") or {}), **dataclasses.asdict(simulation)}

        def absolute(section: str, key: str) -> None:
            part = data.get(section) or {}
            value = part.get(key)
            if isinstance(value, str) and not value.startswith("sumo:"):
                part[key] = str(self.resolve(value))
            elif isinstance(value, list):
                part[key] = [v if v.startswith("sumo:") else str(self.resolve(v)) for v in value]

        for section, key in (("network", "net_file"), ("network", "sumocfg"),
                             ("network", "route_files"), ("network", "additional_files"),
                             ("traffic", "route_files")):  # fmt: skip
            absolute(section, key)
        header = f"# {self.path} (sha256 {self.sha256}) as run by platoon-sumo\n"
        return header + yaml.safe_dump(data, sort_keys=False)

    def resolve(self, value: str) -> Path:
        if value.startswith("sumo:"):
            return resolve_sumo_path(value)
        p = Path(value)
        return p if p.is_absolute() else (self.path.parent / p).resolve()


def load_scenario(path: str | Path) -> ScenarioSource:
    """Read and shape-check a scenario file (no network access yet)."""
    p = Path(path)
    shown = str(path)
    text, data = read_mapping(p, shown)
    if "network" not in data:
        raise ScenarioError(shown, "network", "required key is missing")
    default_name = re.sub(r"[^A-Za-z0-9_.-]", "_", p.stem).strip("_.-")[:64] or "scenario"
    data = {"name": default_name, **data}
    scenario = load_dataclass(Scenario, data, shown)
    _check_horizons(scenario, shown)
    return ScenarioSource(scenario, p.resolve(), text)


def _check_horizons(sc: Scenario, file: str) -> None:
    """Demand ends no later than the simulation: a horizon beyond it only costs time and
    memory (random trips are generated up to it before the run starts)."""
    end = sc.simulation.end_s

    def within(value: float | None, key: str) -> None:
        if value is not None and value > end:
            raise ScenarioError(
                file, key, f"{value:g} s is after the simulation's end ({end:g} s)",
                "it must be <= simulation.end_s",
            )  # fmt: skip

    rt = sc.traffic.random_trips
    if rt is not None:
        within(rt.begin_s, "traffic.random_trips.begin_s")
        within(rt.end_s, "traffic.random_trips.end_s")
        span = (rt.end_s if rt.end_s is not None else end) - rt.begin_s
        if span <= 0:
            raise ScenarioError(file, "traffic.random_trips.end_s", "must be after begin_s")
        if span / rt.period_s > MAX_RANDOM_TRIPS:
            raise ScenarioError(
                file, "traffic.random_trips.period_s",
                f"{span:g} s every {rt.period_s:g} s are {span / rt.period_s:.0f} departures "
                f"(at most {MAX_RANDOM_TRIPS})", "use a longer period or a shorter span",
            )  # fmt: skip
    for i, flow in enumerate(sc.traffic.flows):
        within(flow.begin_s, f"traffic.flows[{i}].begin_s")
        within(flow.end_s, f"traffic.flows[{i}].end_s")


# --------------------------------------------------------------------------- preparing


@dataclass(frozen=True)
class SensorPlan:
    name: str
    model: type[SensorModel]
    params: Any


#: A platoon longer than its first edge starts with its leader this far before the
#: edge's end (not on a stop line) [m].
DEPART_BEFORE_END_M = 2.0


@dataclass(frozen=True)
class MemberPlan:
    vehicle_id: str
    platoon_id: str
    index: int
    role: str
    controller_cls: type[Controller]
    controller_params: Any
    depart_pos_m: float
    sensors: tuple[SensorPlan, ...] = ()
    waits_for_room: bool = False
    """The platoon does not fit on its first edge: this member departs after the one
    ahead of it, once that one has left room (at the rearmost slot that fits)."""
    sumo_car_following: SumoCarFollowing | None = None
    """SUMO's car-following model drives this member's speed (its controller asks for
    it, e.g. `sumo_driver`): its own vehicle type, `PlatoonPlan.type_id_of`."""

    @property
    def laser(self) -> LaserConfig | None:
        """The member's laser scanner, if it has one."""
        for sensor in self.sensors:
            if isinstance(sensor.params, LaserConfig):
                return sensor.params
        return None


@dataclass(frozen=True)
class PlatoonPlan:
    config: PlatoonConfig
    edges: tuple[str, ...]
    depart_lane: int
    members: tuple[MemberPlan, ...]
    model: type[VehicleModel]
    limits: MotionLimits
    """The vehicle's limits, built and checked once (the loop reads them every step)."""

    @property
    def type_id(self) -> str:
        return f"platoon_{self.config.id}"

    def type_id_of(self, member: MemberPlan) -> str:
        """The member's SUMO vehicle type: the platoon's, or its role's own where SUMO's
        car-following model drives it."""
        if member.sumo_car_following is None:
            return self.type_id
        return f"{self.type_id}_{member.role}"


@dataclass(frozen=True)
class RunPlan:
    """A scenario checked against its files and network, ready to run."""

    source: ScenarioSource
    net_file: Path
    route_files: tuple[Path, ...]
    additional_files: tuple[Path, ...]
    network: Network
    platoons: tuple[PlatoonPlan, ...]

    @property
    def scenario(self) -> Scenario:
        return self.source.scenario


def _steers(actuation: str) -> bool:
    """Does this actuation move vehicles sideways (and need SUMO's sublane model)? An
    unknown name is reported where the platoon is checked."""
    try:
        return bool(ACTUATORS.get(actuation).steers)
    except LookupError:
        return False


def prepare(source: ScenarioSource) -> RunPlan:
    """Check a loaded scenario against the filesystem and the network."""
    sc = source.scenario
    file = str(source.path)
    net_file, cfg_routes, cfg_adds = _network_files(source)
    routes_keyed = [(r, "network.sumocfg") for r in cfg_routes]
    routes_keyed += [
        (_existing(source, v, key), key)
        for section in ("network", "traffic")
        for i, v in enumerate(getattr(sc, section).route_files)
        for key in [f"{section}.route_files[{i}]"]
    ]
    adds_keyed = [(a, "network.sumocfg") for a in cfg_adds]
    adds_keyed += [
        (_existing(source, v, f"network.additional_files[{i}]"), f"network.additional_files[{i}]")
        for i, v in enumerate(sc.network.additional_files)
    ]
    route_files = tuple(r for r, _ in routes_keyed)
    additional = tuple(a for a, _ in adds_keyed)
    try:
        network = Network(net_file)
    except Exception as exc:  # sumolib raises plain exceptions on a broken file
        raise ScenarioError(file, "network", f"cannot read network {net_file}: {exc}") from None
    for path, key, is_route in [(*a, False) for a in adds_keyed] + [
        (*r, True) for r in routes_keyed
    ]:
        try:
            check_route_file(path, network) if is_route else check_xml(path)
        except InputFileError as exc:
            raise ScenarioError(file, key, str(exc)) from None
    _check_traffic(sc, network, file)
    declared = [(p, f"platoons[{i}]") for i, p in enumerate(sc.platoons) if not p.template]
    # flows' platoons too: a template naming no actuation gets the cars' default, sublane
    every = [*declared, *_platoons_from_flows(sc, file)]
    steered = [(key, p.actuation_name) for p, key in every if _steers(p.actuation_name)]
    if steered and sc.simulation.lateral_resolution_m is None:
        raise ScenarioError(
            file, "simulation.lateral_resolution_m",
            f"{steered[0][0]} uses {steered[0][1]} actuation, which needs SUMO's sublane model",
            "set it (e.g. 0.8), or give the platoons `actuation: lane`",
        )  # fmt: skip
    platoons = tuple(_prepare_platoon(p, key, network, file) for p, key in every)
    return RunPlan(source, net_file, route_files, additional, network, platoons)


def _existing(source: ScenarioSource, value: str, key: str) -> Path:
    path = source.resolve(value)
    if not path.is_file():
        raise ScenarioError(str(source.path), key, f"file not found: {path}")
    return path


def _network_files(source: ScenarioSource) -> tuple[Path, tuple[Path, ...], tuple[Path, ...]]:
    net = source.scenario.network
    if net.net_file is not None:
        return _existing(source, net.net_file, "network.net_file"), (), ()
    assert net.sumocfg is not None  # guaranteed by NetworkConfig
    cfg = _existing(source, net.sumocfg, "network.sumocfg")
    try:
        root = ET.parse(cfg).getroot()
    except ET.ParseError as exc:
        raise ScenarioError(str(source.path), "network.sumocfg", f"{cfg}: {exc}") from None

    def values(tag: str) -> list[Path]:
        found = root.find(f"input/{tag}")
        if found is None:
            return []
        return [(cfg.parent / v.strip()).resolve() for v in found.get("value", "").split(",") if v]

    nets = values("net-file")
    if not nets:
        raise ScenarioError(str(source.path), "network.sumocfg", f"{cfg} names no net-file")
    for p in [*nets, *values("route-files"), *values("additional-files")]:
        if not p.is_file():
            raise ScenarioError(str(source.path), "network.sumocfg", f"{cfg} names missing {p}")
    return nets[0], tuple(values("route-files")), tuple(values("additional-files"))


def _check_traffic(sc: Scenario, network: Network, file: str) -> None:
    vclass_of = {t.id: t.vclass for t in sc.traffic.vehicle_types}
    type_ids = set(vclass_of)
    for i, flow in enumerate(sc.traffic.flows):
        key = f"traffic.flows[{i}]"
        vclass = vclass_of.get(flow.type or "", "passenger")
        _route_edges(network, file, key, (), flow.from_edge, flow.to_edge, flow.via_edges, vclass)
        if flow.type is not None and flow.type not in type_ids | {"DEFAULT_VEHTYPE"}:
            raise ScenarioError(
                file, f"{key}.type", f"unknown vehicle type '{flow.type}'",
                "define it under traffic.vehicle_types "
                f"(defined: {', '.join(sorted(type_ids)) or 'none'})",
            )  # fmt: skip


def _route_edges(
    network: Network,
    file: str,
    key: str,
    edges: tuple[str, ...],
    from_edge: str | None,
    to_edge: str | None,
    via: tuple[str, ...],
    vclass: str = "passenger",
) -> tuple[str, ...]:
    try:
        if edges:
            network.check_edges(edges, vclass)
            return edges
        assert from_edge is not None and to_edge is not None
        return tuple(network.shortest_route(from_edge, to_edge, via, vclass))
    except RouteError as exc:
        if edges:
            where = f"{key}.edges[{exc.index}]" if exc.index is not None else f"{key}.edges"
        else:
            waypoints = ["from_edge", *[f"via_edges[{j}]" for j in range(len(via))], "to_edge"]
            idx = exc.index if exc.index is not None else None
            where = f"{key}.{waypoints[idx]}" if idx is not None else key
        raise ScenarioError(file, where, str(exc), exc.hint) from None


def _platoons_from_flows(sc: Scenario, file: str) -> list[tuple[PlatoonConfig, str]]:
    """Platoons that replace `platoon_share` of each flow, spread evenly over its span."""
    templates = {p.id: p for p in sc.platoons if p.template}
    out: list[tuple[PlatoonConfig, str]] = []
    for i, flow in enumerate(sc.traffic.flows):
        if flow.platoon_share == 0:
            continue
        key = f"traffic.flows[{i}]"
        template = templates.get(flow.platoon_template or "")
        if template is None:
            raise ScenarioError(
                file, f"{key}.platoon_template",
                f"no platoon with id '{flow.platoon_template}' and template: true",
                did_you_mean(flow.platoon_template or "", templates),
            )  # fmt: skip
        end_s = flow.end_s if flow.end_s is not None else sc.simulation.end_s
        per_hour = flow.vehs_per_hour * flow.platoon_share / template.members
        count = int((end_s - flow.begin_s) * per_hour / 3600.0)
        if count > MAX_FLOW_PLATOONS:
            raise ScenarioError(
                file, f"{key}.platoon_share",
                f"would insert {count} platoons (at most {MAX_FLOW_PLATOONS})",
                "lower platoon_share or vehs_per_hour, or shorten the flow",
            )  # fmt: skip
        period = 3600.0 / per_hour
        route = RouteConfig(
            from_edge=flow.from_edge, to_edge=flow.to_edge, via_edges=flow.via_edges
        )
        for k in range(count):
            copy = dataclasses.replace(
                template, id=f"{template.id}_f{i}_{k}", route=route,
                depart_s=flow.begin_s + (k + 0.5) * period, template=False,
            )  # fmt: skip
            out.append((copy, key))
    return out


def _prepare_platoon(p: PlatoonConfig, key: str, network: Network, file: str) -> PlatoonPlan:
    r = p.route
    assert r is not None  # PlatoonConfig requires it for platoons that drive
    edges = _route_edges(
        network, file, f"{key}.route", r.edges, r.from_edge, r.to_edge, r.via_edges,
        p.vehicle.vclass,
    )  # fmt: skip
    first = edges[0]
    lanes = network.lane_count(first)
    vclass = p.vehicle.vclass
    allowed = network.first_lane_allowing(first, vclass)
    depart_lane = p.depart_lane if p.depart_lane is not None else allowed
    if depart_lane is None:
        raise ScenarioError(
            file, f"{key}.route", f"no lane of the first edge '{first}' allows vClass {vclass}"
        )
    if not 0 <= depart_lane < lanes:
        raise ScenarioError(
            file,
            f"{key}.depart_lane",
            f"edge '{first}' has lanes 0..{lanes - 1}, got {depart_lane}",
        )
    if not network.lane_allows(first, depart_lane, vclass):
        raise ScenarioError(
            file, f"{key}.depart_lane",
            f"lane {depart_lane} of edge '{first}' does not allow vClass {vclass}",
            f"lane {allowed} is the rightmost that does",
        )  # fmt: skip
    need = p.members * p.vehicle.length_m + (p.members - 1) * p.spacing_m
    edge_len = network.edge_length_m(first)
    if p.depart_pos_m is not None and not 0 < p.depart_pos_m <= edge_len:
        raise ScenarioError(
            file, f"{key}.depart_pos_m",
            f"must be in (0, {edge_len:.1f}] m, the length of edge '{first}'",
        )  # fmt: skip
    if edge_len < p.vehicle.length_m:
        raise ScenarioError(
            file, f"{key}.route",
            f"the first edge '{first}' ({edge_len:.1f} m) is shorter than one member "
            f"({p.vehicle.length_m} m)", "start the route on a longer edge",
        )  # fmt: skip
    depart_pos = p.depart_pos_m
    if depart_pos is None:  # room for all, else the leader a little before the edge's end
        depart_pos = min(need + 0.1, max(edge_len - DEPART_BEFORE_END_M, p.vehicle.length_m))
    if depart_pos < p.vehicle.length_m:
        raise ScenarioError(
            file, f"{key}.depart_pos_m",
            f"the leader's front at {depart_pos:.1f} m leaves no room for its "
            f"{p.vehicle.length_m} m length on edge '{first}'",
            f"use at least {p.vehicle.length_m}",
        )  # fmt: skip
    slot_m = p.vehicle.length_m + p.spacing_m
    fitting = min(p.members, int((depart_pos - p.vehicle.length_m) // slot_m) + 1)
    members = []
    actuator = ACTUATORS.get(p.actuation_name)
    for k, vid in enumerate(p.member_ids()):
        role = "leader" if k == 0 else "follower"
        ctrl = p.leader if k == 0 else p.follower
        ctrl_key = f"{key}.{role}"
        try:
            cls = CONTROLLERS.get(ctrl.type)
        except LookupError as exc:
            raise ScenarioError(file, f"{ctrl_key}.type", str(exc)) from None
        params = load_dataclass(cls.Params, dict(ctrl.params), file, f"{ctrl_key}.params")
        # members beyond the first edge's room wait at the rearmost slot that fits
        pos = depart_pos - min(k, fitting - 1) * slot_m
        sensors = _sensors(ctrl, file, ctrl_key)
        sumo_cf = sumo_car_following(cls, params)
        if sumo_cf is not None and (not actuator.sumo_drives or actuator.steers):
            raise ScenarioError(
                file, f"{key}.actuation",
                f"the {role}s' controller '{ctrl.type}' leaves the speed to SUMO's "
                f"car-following model, which drives a car along its lanes only; got "
                f"'{p.actuation_name}'", "use `actuation: lane`",
            )  # fmt: skip
        members.append(
            MemberPlan(vid, p.id, k, role, cls, params, pos, sensors, k >= fitting, sumo_cf)
        )
    return PlatoonPlan(
        config=p,
        edges=edges,
        depart_lane=depart_lane,
        members=tuple(members),
        model=VEHICLE_MODELS.get(p.vehicle.model),
        limits=p.vehicle.limits(),
    )


def _sensors(role: RoleConfig, file: str, key: str) -> tuple[SensorPlan, ...]:
    """The role's laser (`sensor`, named "laser") and further sensors, checked."""
    plans: list[SensorPlan] = []
    laser = _laser(role.sensor, file, f"{key}.sensor")
    if laser is not None:
        plans.append(SensorPlan("laser", SENSORS.get("laser"), laser))
    for i, spec in enumerate(role.sensors):
        at = f"{key}.sensors[{i}]"
        try:
            model = SENSORS.get(spec.type)
        except LookupError as exc:
            raise ScenarioError(file, f"{at}.type", str(exc)) from None
        name = spec.name or spec.type
        if any(p.name == name for p in plans):
            raise ScenarioError(
                file, f"{at}.name", f"a sensor named '{name}' already exists",
                "give each sensor its own name",
            )  # fmt: skip
        params = load_dataclass(model.Params, dict(spec.params), file, f"{at}.params")
        plans.append(SensorPlan(name, model, params))
    return tuple(plans)


def _laser(sensor: SensorConfig | None, file: str, key: str) -> LaserConfig | None:
    if sensor is None:
        return None
    fields = [f.name for f in dataclasses.fields(LaserConfig)]
    for name in sensor.overrides:
        if name not in fields:
            raise ScenarioError(
                file, f"{key}.overrides.{name}",
                f"unknown laser setting (allowed: {', '.join(fields)})",
                did_you_mean(name, fields),
            )  # fmt: skip
    try:
        return LaserConfig.preset(sensor.preset, **dict(sensor.overrides))
    except FieldError as exc:
        where = f"{key}.overrides.{exc.key}" if exc.key in sensor.overrides else f"{key}.preset"
        raise ScenarioError(file, where, exc.message) from None
    except (TypeError, ValueError) as exc:
        raise ScenarioError(file, f"{key}.overrides", str(exc)) from None
