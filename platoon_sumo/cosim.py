"""The co-simulation loop: SUMO moves the humans, we move the platoons.

One step (dt = SUMO's step length), as `CoSimulation.step` runs it:
  insert due platoons (whole, when their first lane has room) -> laser scans at each
  sensor's rate -> controllers -> supervisor -> vehicle models -> poses pushed into SUMO
  (planar actuation) or speeds handed to SUMO's driver (lane actuation) ->
  simulationStep -> arrivals -> snapshot of the world (read once) -> departures ->
  states of SUMO-driven members read back -> route progress (signals, links, lane
  changes, vehicle ahead) -> platoon relations and events -> collision check -> hooks
  (recorders and later features plug in there without editing this loop).
  docs/design.md walks through each stage.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.control import Command, Controller, Observation
from platoon_sumo.geometry import (
    footprints_from_front_bumper,
    overlapping_pairs,
    rectangles_crossing_segments,
)
from platoon_sumo.path import LaneChange, RoutePath
from platoon_sumo.platoon import LinkMonitor, bumper_gap_m, predecessor_ids, rays_on_target
from platoon_sumo.scenario import MemberPlan, PlatoonPlan, RunPlan
from platoon_sumo.sensors.laser import LaserConfig, LaserScan, sensor_poses
from platoon_sumo.sensors.raycast import scan_many
from platoon_sumo.sumo.backend import SumoBackend
from platoon_sumo.supervisor import EMERGENCY, SUMO_SAFETY, supervise
from platoon_sumo.vehicles import KinematicState, heading_to_yaw_rate
from platoon_sumo.world import (
    LaneChangeAhead,
    LinkAhead,
    SignalAhead,
    VehicleAhead,
    WorldSnapshot,
)

FloatArray = NDArray[np.float64]


@dataclass
class PlatoonVehicle:
    """One of our vehicles while it is in the network."""

    plan: MemberPlan
    platoon: PlatoonPlan
    controller: Controller
    path: RoutePath
    state: KinematicState
    """One-element state of the model's reference point."""
    route_s_m: float = 0.0
    """Front bumper's progress along the route path."""
    lateral_offset_m: float = 0.0
    accel_mps2: float = 0.0
    command: Command = field(default_factory=lambda: Command(0.0))
    """What the controller asked for this step."""
    executed: Command = field(default_factory=lambda: Command(0.0))
    """What the supervisor let through (the vehicle model's input)."""
    supervisor_state: str = ""
    """"" when the command passed unchanged, else what the supervisor enforced."""
    sumo_capped: bool = False
    """Lane actuation: SUMO held the vehicle below its executed command this step."""
    signal: SignalAhead | None = None
    link_ahead: LinkAhead | None = None
    lane_change: LaneChangeAhead | None = None
    vehicle_ahead: VehicleAhead | None = None
    scan: LaserScan | None = None
    predecessor_id: str | None = None
    gap_to_predecessor_m: float | None = None
    """Follower's front-bumper centre to predecessor's rear-bumper centre (ground truth)."""
    predecessor_rays: int | None = None
    """Rays of this step's scan that return from the predecessor (None: no scan)."""

    @property
    def platoon_id(self) -> str:
        return self.plan.platoon_id

    @property
    def sumo_drives(self) -> bool:
        """Lane actuation: SUMO moves it at our commanded speed (else we place it)."""
        return self.platoon.config.actuation == "lane"

    @property
    def index(self) -> int:
        return self.plan.index

    @property
    def id(self) -> str:
        return self.plan.vehicle_id

    @property
    def front_offset_m(self) -> float:
        return self.platoon.config.vehicle.front_offset_m

    def front_bumper(self) -> tuple[float, float]:
        yaw = float(self.state.yaw_rad[0])
        return (
            float(self.state.x_m[0]) + self.front_offset_m * math.cos(yaw),
            float(self.state.y_m[0]) + self.front_offset_m * math.sin(yaw),
        )


#: The other party of a collision with static geometry (walls, kerbs, buildings).
WALL = "<wall>"


@dataclass(frozen=True)
class Collision:
    time_s: float
    vehicle_a: str
    vehicle_b: str


@dataclass(frozen=True)
class RemovedVehicle:
    """A platoon vehicle SUMO could not place on its route any more (taken out)."""

    time_s: float
    vehicle_id: str
    reason: str


@dataclass(frozen=True)
class RedLightViolation:
    time_s: float
    vehicle_id: str
    tls_id: str
    link_index: int
    state: str


@dataclass(frozen=True)
class StepRecord:
    """What happened in one step; handed to every hook."""

    time_s: float
    world: WorldSnapshot
    vehicles: tuple[PlatoonVehicle, ...]
    new_collisions: tuple[Collision, ...]
    new_violations: tuple[RedLightViolation, ...]


class StepHook(Protocol):
    """Something that watches the run (recorders, progress bars, metrics)."""

    def on_start(self, sim: CoSimulation) -> None: ...

    def on_step(self, sim: CoSimulation, record: StepRecord) -> None: ...

    def on_end(self, sim: CoSimulation) -> None: ...


@dataclass
class RunCounters:
    collisions: list[Collision] = field(default_factory=list)
    red_light_violations: list[RedLightViolation] = field(default_factory=list)
    sumo_collisions: int = 0
    sumo_collisions_with_platoons: int = 0
    teleports: int = 0
    emergency_brakings: int = 0
    sumo_speed_caps: int = 0
    """Lane actuation: times SUMO's safety layer held a vehicle below its command."""
    removed_off_route: list[RemovedVehicle] = field(default_factory=list)
    platoon_arrived: list[str] = field(default_factory=list)
    platoon_departed: list[str] = field(default_factory=list)
    arrived_total: int = 0
    departed_total: int = 0
    steps: int = 0


class CoSimulation:
    """Runs a RunPlan on a started SumoBackend; `run()` steps until the end time."""

    def __init__(
        self,
        plan: RunPlan,
        backend: SumoBackend,
        hooks: Sequence[StepHook] = (),
        rng: np.random.Generator | None = None,
        static_segments: FloatArray | None = None,
    ):
        self.plan = plan
        self.backend = backend
        self.hooks = list(hooks)
        sim = plan.scenario.simulation
        self.dt_s = sim.step_s
        self.end_s = sim.end_s
        self.rng = rng if rng is not None else np.random.default_rng(sim.seed)
        self.static_segments = static_segments
        self.active: dict[str, PlatoonVehicle] = {}
        self.counters = RunCounters()
        self._pending = sorted(plan.platoons, key=lambda p: (p.config.depart_s, p.config.id))
        """Platoons not inserted yet (due ones wait for room on their first lane)."""
        self._waiting_insert: dict[str, MemberPlan] = {}
        self._paths: dict[tuple[str, ...], RoutePath] = {}
        self._lanes: dict[str, tuple[FloatArray, float]] = {}
        self._overlapping: set[tuple[str, ...]] = set()
        self._sumo_contacts: set[tuple[str, str]] = set()
        self._linked: dict[str, bool] = {}
        self.links = LinkMonitor()
        """Splits, re-formations and cut-ins of every platoon."""
        self._last_scan_s: dict[str, float] = {}
        self.world: WorldSnapshot | None = None
        self.rects: FloatArray = np.empty((0, 5))
        """Footprints of `world`'s vehicles (ours from our exact model state)."""

    # ------------------------------------------------------------------ running

    def run(self) -> RunCounters:
        for hook in self.hooks:
            hook.on_start(self)
        self.world = self.backend.snapshot()
        self.rects = self.footprints(self.world)
        while self.backend.time_s < self.end_s - 1e-9:
            self.step()
        for hook in self.hooks:
            hook.on_end(self)
        return self.counters

    def step(self) -> None:
        world = self.world if self.world is not None else self.backend.snapshot()
        self._insert_due_platoons(world.time_s)
        vehicles = list(self.active.values())
        if vehicles:
            self._scan(vehicles, world)
            self._control(vehicles, world)
        self.backend.step()
        self.counters.steps += 1
        self.counters.teleports += self.backend.teleport_count()
        sumo_contacts = {(a, b) for a, b, _ in self.backend.sumo_collisions()}
        new_contacts = sumo_contacts - self._sumo_contacts
        self.counters.sumo_collisions += len(new_contacts)
        self.counters.sumo_collisions_with_platoons += sum(
            a in self.active or b in self.active for a, b in new_contacts
        )
        self._sumo_contacts = sumo_contacts
        self._handle_arrivals()
        world = self.world = self.backend.snapshot()
        self._handle_departures(world)
        self._read_sumo_driven(world)
        violations = self._update_route_progress(list(self.active.values()))
        vehicles = list(self.active.values())  # those that reached their route's end are gone
        self.rects = self.footprints(world)
        self._update_predecessors(vehicles, world)
        self._update_links(vehicles, world.time_s)
        collisions = self._check_collisions(world)
        record = StepRecord(
            world.time_s, world, tuple(vehicles), tuple(collisions), tuple(violations)
        )
        for hook in self.hooks:
            hook.on_step(self, record)

    # ------------------------------------------------------------------ insertion

    @property
    def pending_platoons(self) -> list[PlatoonPlan]:
        """Platoons that were never inserted (their depart time or first-lane room not yet come)."""
        return list(self._pending)

    def _insert_due_platoons(self, time_s: float) -> None:
        """Insert each due platoon as a whole once its first lane has room for all members
        (a platoon never starts scattered behind other traffic); later ones keep waiting."""
        due = [p for p in self._pending if p.config.depart_s <= time_s + 1e-9]
        for platoon in due:
            cfg = platoon.config
            lane = f"{platoon.edges[0]}_{platoon.depart_lane}"
            front = platoon.members[0].depart_pos_m
            rear = platoon.members[-1].depart_pos_m - cfg.vehicle.length_m
            # the rear member's follower keeps its minGap; the leader must not touch anyone ahead
            if not self.backend.lane_is_free(lane, rear - 10.0, front + cfg.spacing_m):
                continue
            self._pending.remove(platoon)
            for member in platoon.members:
                self.backend.add_vehicle(
                    member.vehicle_id,
                    platoon.edges,
                    platoon.type_id,
                    platoon.depart_lane,
                    member.depart_pos_m,
                    sumo_drives=cfg.actuation == "lane",
                )
                self._waiting_insert[member.vehicle_id] = member

    def _platoon_of(self, member: MemberPlan) -> PlatoonPlan:
        return next(p for p in self.plan.platoons if p.config.id == member.platoon_id)

    def _path_for(self, platoon: PlatoonPlan) -> RoutePath:
        key = (*platoon.edges, str(platoon.depart_lane), str(platoon.config.vehicle.length_m))
        if key not in self._paths:
            spacing = min(max(platoon.config.vehicle.length_m / 8, 0.02), 0.5)
            self._paths[key] = self.plan.network.route_path(
                platoon.edges, spacing_m=spacing, first_lane=platoon.depart_lane,
                vclass=platoon.config.vehicle.vclass,
            )  # fmt: skip
        return self._paths[key]

    def _handle_departures(self, world: WorldSnapshot) -> None:
        for vid in self.backend.departed_ids():
            self.counters.departed_total += 1
            member = self._waiting_insert.pop(vid, None)
            if member is None:
                continue
            platoon = self._platoon_of(member)
            i = world.index[vid]
            yaw = float(world.yaw_rad[i])
            offset = platoon.config.vehicle.front_offset_m
            state = KinematicState.of(
                float(world.front_x_m[i]) - offset * math.cos(yaw),
                float(world.front_y_m[i]) - offset * math.sin(yaw),
                yaw,
                0.0,
            )
            controller = member.controller_cls(member.controller_params)
            controller.reset()
            path = self._path_for(platoon)
            vehicle = PlatoonVehicle(member, platoon, controller, path, state)
            fx, fy = vehicle.front_bumper()
            point = path.project(fx, fy)
            vehicle.route_s_m, vehicle.lateral_offset_m = point.s_m, point.lateral_offset_m
            vehicle.signal = self.backend.next_signal(vid)
            self.active[vid] = vehicle
            self.counters.platoon_departed.append(vid)

    def _handle_arrivals(self) -> None:
        arrived = self.backend.arrived_ids()
        self.counters.arrived_total += len(arrived)
        self.backend.forget(arrived)
        for vid in arrived:
            if self.active.pop(vid, None) is not None:
                self.counters.platoon_arrived.append(vid)

    # ------------------------------------------------------------------ sensing + control

    def _scan(self, vehicles: list[PlatoonVehicle], world: WorldSnapshot) -> None:
        """Scans for equipped vehicles whose sensor period has elapsed, batched per config."""
        due: dict[LaserConfig, list[PlatoonVehicle]] = {}
        for v in vehicles:
            laser = v.plan.laser
            if laser is None:
                continue
            last = self._last_scan_s.get(v.id, -math.inf)
            if world.time_s - last >= 1.0 / laser.rate_hz - 1e-9:
                due.setdefault(laser, []).append(v)
        if not due:
            return
        rects = self.rects
        predecessors = predecessor_ids(vehicles)
        for laser, group in due.items():
            bumpers = np.array([v.front_bumper() for v in group])
            yaws = np.array([float(v.state.yaw_rad[0]) for v in group])
            origins, headings = sensor_poses(bumpers[:, 0], bumpers[:, 1], yaws, laser)
            exclude = np.array([world.index.get(v.id, -1) for v in group], dtype=np.int64)
            ranges = scan_many(
                origins, headings, laser, rectangles=rects, segments=self.static_segments,
                exclude=exclude, rng=self.rng,
            )  # fmt: skip
            for k, v in enumerate(group):
                v.scan = LaserScan.from_ranges(
                    laser, ranges[k], origins[k], float(headings[k]), world.time_s
                )
                self._last_scan_s[v.id] = world.time_s
                pred = predecessors.get(v.id)
                v.predecessor_rays = (
                    rays_on_target(v.scan, laser, rects[world.index[pred]])
                    if pred is not None and pred in world.index
                    else 0
                )

    def footprints(self, world: WorldSnapshot) -> FloatArray:
        """Rectangles of every vehicle; ours from our own (exact) model state."""
        x, y, yaw = world.front_x_m.copy(), world.front_y_m.copy(), world.yaw_rad.copy()
        for vid, v in self.active.items():
            i = world.index.get(vid)
            if i is not None:
                x[i], y[i] = v.front_bumper()
                yaw[i] = float(v.state.yaw_rad[0])
        return footprints_from_front_bumper(x, y, yaw, world.length_m, world.width_m)

    def _control(self, vehicles: list[PlatoonVehicle], world: WorldSnapshot) -> None:
        for v in vehicles:
            cfg = v.platoon.config.vehicle
            obs = Observation(
                time_s=world.time_s,
                dt_s=self.dt_s,
                vehicle_id=v.id,
                role=v.plan.role,
                x_m=float(v.state.x_m[0]),
                y_m=float(v.state.y_m[0]),
                yaw_rad=float(v.state.yaw_rad[0]),
                speed_mps=float(v.state.speed_mps[0]),
                front_offset_m=cfg.front_offset_m,
                length_m=cfg.length_m,
                width_m=cfg.width_m,
                limits=v.platoon.limits,
                path=v.path,
                lane_offset_m=v.lateral_offset_m if v.sumo_drives else 0.0,
                signal=v.signal,
                link_ahead=v.link_ahead,
                lane_change=v.lane_change,
                vehicle_ahead=v.vehicle_ahead,
                scan=v.scan,
            )
            v.command = v.controller.step(obs)
            v.executed, enforced = supervise(v.platoon.config.supervisor, obs, v.command)
            if enforced == EMERGENCY and v.supervisor_state != EMERGENCY:
                self.counters.emergency_brakings += 1
            v.supervisor_state = enforced
        driven = [v for v in vehicles if v.sumo_drives]
        if driven:
            self.backend.set_speeds(
                [v.id for v in driven], np.array([v.executed.speed_mps for v in driven])
            )
            self.backend.request_lane_changes(
                {v.id: v.executed.lane_change for v in driven if v.executed.lane_change}
            )
        # Integrate per platoon: members share a model and limits, so one vectorised call.
        by_platoon: dict[str, list[PlatoonVehicle]] = {}
        for v in vehicles:
            if not v.sumo_drives:
                by_platoon.setdefault(v.platoon.config.id, []).append(v)
        if not by_platoon:
            return
        ids: list[str] = []
        fx, fy, yaws, speeds = [], [], [], []
        for group in by_platoon.values():
            platoon = group[0].platoon
            limits = platoon.limits
            state = KinematicState.of(
                [float(v.state.x_m[0]) for v in group],
                [float(v.state.y_m[0]) for v in group],
                [float(v.state.yaw_rad[0]) for v in group],
                [float(v.state.speed_mps[0]) for v in group],
            )
            yaw_rate = np.array(
                [
                    float(heading_to_yaw_rate(v.executed.heading_rad, v.state.yaw_rad[0],
                                              self.dt_s, limits.max_yaw_rate_radps)[0])
                    if v.executed.heading_rad is not None else v.executed.yaw_rate_radps
                    for v in group
                ]
            )  # fmt: skip
            speed_cmd = np.array([v.executed.speed_mps for v in group])
            new = platoon.model().step(state, speed_cmd, yaw_rate, limits, self.dt_s)
            for k, v in enumerate(group):
                v.accel_mps2 = (float(new.speed_mps[k]) - float(v.state.speed_mps[0])) / self.dt_s
                v.state = new.take([k])
                bx, by = v.front_bumper()
                ids.append(v.id)
                fx.append(bx)
                fy.append(by)
                yaws.append(float(new.yaw_rad[k]))
                speeds.append(float(new.speed_mps[k]))
        failed = self.backend.move(
            ids, np.array(fx), np.array(fy), np.array(yaws), np.array(speeds)
        )
        for vid, reason in failed.items():  # off its route: out of the run, reported
            self.backend.discard(vid)
            self.backend.forget([vid])
            del self.active[vid]
            self.counters.removed_off_route.append(RemovedVehicle(world.time_s, vid, reason))

    def _read_sumo_driven(self, world: WorldSnapshot) -> None:
        """Lane actuation: SUMO moved the vehicle; its pose and speed become the state.

        Where SUMO's speed stays clearly below what the command and the acceleration
        limit allowed, SUMO's safety layer acted: named in the supervisor state and
        counted once per episode."""
        for v in self.active.values():
            i = world.index.get(v.id)
            if not v.sumo_drives or i is None:
                continue
            yaw = float(world.yaw_rad[i])
            speed = float(world.speed_mps[i])
            previous = float(v.state.speed_mps[0])
            offset = v.front_offset_m
            v.state = KinematicState.of(
                float(world.front_x_m[i]) - offset * math.cos(yaw),
                float(world.front_y_m[i]) - offset * math.sin(yaw),
                yaw,
                speed,
            )
            v.accel_mps2 = (speed - previous) / self.dt_s
            allowed = min(
                v.executed.speed_mps, previous + v.platoon.limits.max_accel_mps2 * self.dt_s
            )
            capped = speed < allowed - 0.01
            if capped and not v.sumo_capped:
                self.counters.sumo_speed_caps += 1
            v.sumo_capped = capped
            if capped and not v.supervisor_state:
                v.supervisor_state = SUMO_SAFETY

    # ------------------------------------------------------------------ bookkeeping

    def _update_route_progress(self, vehicles: list[PlatoonVehicle]) -> list[RedLightViolation]:
        violations: list[RedLightViolation] = []
        time_s = self.backend.time_s
        for v in vehicles:
            fx, fy = v.front_bumper()
            window = max(10.0, 4.0 * v.platoon.config.vehicle.length_m)
            point = v.path.project(fx, fy, s_hint_m=v.route_s_m, window_m=window)
            travelled_m = max(point.s_m - v.route_s_m, 0.0)
            v.route_s_m, v.lateral_offset_m = point.s_m, point.lateral_offset_m
            previous, v.signal = v.signal, self.backend.next_signal(v.id)
            v.vehicle_ahead = self.backend.vehicle_ahead(v.id, self._ahead_horizon_m(v))
            v.link_ahead = self.backend.link_ahead(v.id)
            v.lane_change = self._lane_change_ahead(v)
            if (
                previous is not None
                and previous.state in ("r", "u")
                and crossed_stop_line(previous, v.signal, travelled_m)
            ):
                violation = RedLightViolation(
                    time_s, v.id, previous.tls_id, previous.link_index, previous.state
                )
                violations.append(violation)
                self.counters.red_light_violations.append(violation)
            if v.route_s_m >= v.path.length_m - 0.05:
                self.backend.remove(v.id)
                self.backend.forget([v.id])
                del self.active[v.id]
                self.counters.platoon_arrived.append(v.id)
                self.counters.arrived_total += 1
        return violations

    def _lane_change_ahead(self, v: PlatoonVehicle) -> LaneChangeAhead | None:
        """Is the target lane of the next lane change free for the whole move?

        Each vehicle on the target lane(s) is moved forward at its own speed and compared
        with where we will be at five instants of the move (entering to completing it):
        it must stay a time gap of its own behind us or a gap of ours ahead. During the
        move, the nearest vehicle ahead on the target lane is reported for braking.
        """
        change = None if v.sumo_drives else v.path.next_lane_change(v.route_s_m)
        if change is None:  # SUMO makes a SUMO-driven vehicle's lane changes
            return None
        distance = change.begin_s_m - v.route_s_m
        speed = float(v.state.speed_mps[0])
        length = v.platoon.config.vehicle.length_m
        if distance > max(60.0, 8.0 * speed) + 10.0 * length:
            return None
        occupants = [
            o for lane in change.target_lane_ids for o in self.backend.lane_occupants(lane)
        ]
        move_m = change.end_s_m - change.begin_s_m
        if distance <= 0.0:  # under way: the vehicle ahead in the target lane, and sideways
            own = change.begin_lane_pos_m - distance
            ahead = [(pos - other_len - own, vid, spd) for vid, pos, spd, other_len in occupants
                     if pos - other_len > own - 1e-9]  # fmt: skip
            leader = VehicleAhead(min(ahead)[1], min(ahead)[0], min(ahead)[2]) if ahead else None
            hold = self._sideways_hold_m(v, change, occupants)
            if hold is not None:
                return LaneChangeAhead(hold, clear=False, target_leader=leader)
            return LaneChangeAhead(distance, clear=True, target_leader=leader)
        pace = max(speed, 5.0)
        for k in range(5):
            along = k / 4.0 * move_m
            t = (distance + along) / pace
            own = change.begin_lane_pos_m + along
            for _, pos, other_speed, other_len in occupants:
                predicted = pos + other_speed * t
                behind = predicted < own - length - (3.0 + 1.2 * other_speed)
                ahead_ok = predicted - other_len > own + 3.0 + 0.6 * pace
                if not (behind or ahead_ok):
                    return LaneChangeAhead(distance, clear=False)
        hold = self._sideways_hold_m(v, change, occupants)
        if hold is not None:
            return LaneChangeAhead(min(hold, distance), clear=False)
        return LaneChangeAhead(distance, clear=True)

    #: Sideways clearance the route's lane change keeps to a vehicle alongside [m].
    SIDE_CLEARANCE_M = 0.3

    def _sideways_hold_m(
        self,
        v: PlatoonVehicle,
        change: LaneChange,
        occupants: list[tuple[str, float, float, float]],
    ) -> float | None:
        """Distance to where the sideways move must pause, or None to go on.

        The gap check before a lane change predicts the target lane at constant speeds,
        but a move over half a long edge takes many seconds. Worse, SUMO places a moved
        vehicle on the lane under its centre: while our body straddles the lane line, the
        drivers of the target lane do not see it (no shadow-lane registration for
        moveToXY), so they neither brake nor swerve. Hence, every step:

        - a vehicle on the target lane(s) *alongside* (bodies overlapping lengthwise,
          with a margin): the move pauses where our side would come within
          `SIDE_CLEARANCE_M` of its side;
        - a vehicle *coming up from behind* or just ahead, close enough to reach us
          before our centre is over the line: the move pauses before our body touches
          the line; once the body is over the line the move goes on (stopping there
          would leave us invisible to that lane), SUMO sees us once the centre crosses.

        Braking stops the sideways motion too (a car's lateral progress needs forward
        progress). Measured across the occupant's lane, its lateral position included.
        """
        world = self.world
        if world is None or not occupants:
            return None
        speed = float(v.state.speed_mps[0])
        cfg = v.platoon.config.vehicle
        own_front = change.begin_lane_pos_m + (v.route_s_m - change.begin_s_m)
        own_rear = own_front - cfg.length_m
        start = max(v.route_s_m, change.begin_s_m)
        stop = change.end_s_m
        if stop <= start:
            return None
        reach = max(60.0, 4.0 * speed) + speed * speed / 5.0
        samples = np.arange(start, min(stop, start + reach) + 0.5, 0.5)
        points, _ = _path_points(v.path, samples)
        lateral_on: dict[str, FloatArray] = {}
        hold: float | None = None
        for vid, pos, other_speed, other_len in occupants:
            i = world.index.get(vid)
            if vid == v.id or i is None or pos > own_front + 60.0 or pos < own_rear - 80.0:
                continue
            lane = world.lane_ids[i]
            if not lane or lane.startswith(":"):
                continue
            shape, half_lane = self._lane_geometry(lane)
            if lane not in lateral_on:
                lateral_on[lane] = _lateral_offsets(shape, points)
            lateral = lateral_on[lane]
            front = np.array([[world.front_x_m[i], world.front_y_m[i]]])
            other_lat = float(_lateral_offsets(shape, front)[0])
            body_gap = np.abs(lateral - other_lat) - 0.5 * (cfg.width_m + float(world.width_m[i]))
            line_gap = np.abs(lateral) - 0.5 * cfg.width_m - half_lane
            # time until our centre is over the occupant's lane line
            inside = np.nonzero(np.abs(lateral) < half_lane)[0]
            to_centre_m = samples[inside[0] if inside.size else -1] - v.route_s_m
            t_cross = to_centre_m / max(speed, 1.0)
            alongside = pos - other_len < own_front + 1.0 and pos > own_rear - 1.0
            if alongside:
                bad = np.nonzero(body_gap < self.SIDE_CLEARANCE_M)[0]
            else:
                closing = other_speed - speed
                behind_m = 3.0 + 0.5 * other_speed + max(closing, 0.0) * t_cross
                ahead_m = 2.0 + max(-closing, 0.0) * t_cross
                near = pos - other_len < own_front + ahead_m and pos > own_rear - behind_m
                if not near or line_gap[0] < 0.0:
                    continue  # far, or already over the line: commit
                bad = np.nonzero(line_gap < 0.1)[0]
            if bad.size:
                at = float(samples[bad[0]]) - v.route_s_m
                hold = at if hold is None else min(hold, at)
        return hold

    def _lane_geometry(self, lane_id: str) -> tuple[FloatArray, float]:
        """A lane's centre-line and half width (cached)."""
        found = self._lanes.get(lane_id)
        if found is None:
            found = (self.backend.lane_shape(lane_id), 0.5 * self.backend.lane_width(lane_id))
            self._lanes[lane_id] = found
        return found

    @staticmethod
    def _ahead_horizon_m(v: PlatoonVehicle) -> float:
        """Look as far ahead as a full comfortable stop from top speed needs, and more."""
        vehicle = v.platoon.config.vehicle
        return max(20.0 * vehicle.length_m, vehicle.max_speed_mps**2 / vehicle.max_decel_mps2 * 2)

    def _update_predecessors(self, vehicles: list[PlatoonVehicle], world: WorldSnapshot) -> None:
        """Ground truth for metrics: each member's predecessor and the bumper gap to it."""
        predecessors = predecessor_ids(vehicles)
        for v in vehicles:
            pred = predecessors[v.id]
            v.predecessor_id = pred
            v.gap_to_predecessor_m = None
            if pred is not None and pred in world.index and v.id in world.index:
                v.gap_to_predecessor_m = bumper_gap_m(
                    self.rects[world.index[v.id]], self.rects[world.index[pred]]
                )

    def _update_links(self, vehicles: list[PlatoonVehicle], time_s: float) -> None:
        """Splits, re-formations and cut-ins from what each follower perceives."""
        for v in vehicles:
            pred = v.predecessor_id
            if pred is None:
                continue
            if v.plan.laser is not None:
                if v.predecessor_rays is not None:  # keep the last verdict between scans
                    self._linked[v.id] = v.predecessor_rays > 0
            else:
                gap = v.gap_to_predecessor_m
                self._linked[v.id] = gap is not None and gap <= v.platoon.config.split_gap_m
            ahead = v.vehicle_ahead
            intruder = None
            if (
                ahead is not None
                and not ahead.vehicle_id.startswith(v.platoon_id + ".")
                and (v.gap_to_predecessor_m is None or ahead.gap_m < v.gap_to_predecessor_m)
            ):
                intruder = ahead.vehicle_id
            self.links.observe(
                time_s, v.platoon_id, v.id, pred, self._linked.get(v.id, False), intruder
            )

    def _check_collisions(self, world: WorldSnapshot) -> list[Collision]:
        """Footprint overlaps of pairs involving a platoon vehicle (SUMO's check is per lane),
        and platoon vehicles touching walls; each contact counts once, when it begins."""
        if not self.active:
            self._overlapping = set()
            return []
        rects = self.rects
        subjects = np.array([world.index[vid] for vid in self.active if vid in world.index])
        pairs = overlapping_pairs(rects, subjects) if len(subjects) else np.empty((0, 2), int)
        network = self.plan.network
        now = {
            tuple(sorted((world.ids[i], world.ids[j])))
            for i, j in pairs
            if network.same_level(world.lane_ids[i], world.lane_ids[j])
        }
        if self.static_segments is not None and len(subjects):
            hits = rectangles_crossing_segments(rects[subjects], self.static_segments)
            now |= {(world.ids[subjects[i]], WALL) for i in np.unique(hits[:, 0])}
        new = [Collision(world.time_s, a, b) for a, b in sorted(now - self._overlapping)]
        self._overlapping = now
        self.counters.collisions.extend(new)
        return new


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


def _path_points(path: RoutePath, s_m: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Positions and headings of a path at many arc lengths (nearest sample point)."""
    n = len(path.xy_m)
    i = np.clip((np.asarray(s_m) / path.spacing_m).astype(np.int64), 0, n - 2)
    d = path.xy_m[i + 1] - path.xy_m[i]
    t = np.clip((np.asarray(s_m) - i * path.spacing_m) / path.spacing_m, 0.0, 1.0)
    return path.xy_m[i] + d * t[:, None], np.arctan2(d[:, 1], d[:, 0])
