"""Laser follower on synthetic scans and in closed loop with the vehicle models (no SUMO).

The predecessor is a scripted box; scans are ray cast from the follower's front bumper
with ``cast_rays``. The follower never gets ``vehicle_ahead``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from platoon_sumo.config_loader import load_dataclass
from platoon_sumo.control import CONTROLLERS
from platoon_sumo.control.base import Observation
from platoon_sumo.control.laser_follower import LaserFollower, LaserFollowerParams
from platoon_sumo.control.perception import PerceptionParams, TrackerParams
from platoon_sumo.control.route_following import RouteFollowingParams
from platoon_sumo.errors import ScenarioError
from platoon_sumo.geometry import rectangles_overlap
from platoon_sumo.path import RoutePath
from platoon_sumo.sensors.laser import LaserConfig, LaserScan
from platoon_sumo.sensors.raycast import cast_rays
from platoon_sumo.vehicles import Bicycle, KinematicState, MotionLimits, Unicycle

CAR_LIMITS = MotionLimits(15.0, 2.5, 7.5, 1.0, max_steer_rad=0.6, wheelbase_m=2.7)
CAR_FRONT = 3.6  # rear axle to front bumper of a 4.5 m car
CAR_LEN, CAR_WIDTH = 4.5, 1.8
CAR_LASER = LaserConfig.preset("utm30lx", noise_std_m=0.01)

ROBOT_LIMITS = MotionLimits(1.0, 0.5, 1.5, 2.0)
ROBOT_FRONT = 0.15
ROBOT_LEN, ROBOT_WIDTH = 0.3, 0.25
ROBOT_LASER = LaserConfig(-math.radians(60), math.radians(60), 720, 0.3, 2.0, noise_std_m=0.003)
ROBOT_PARAMS = LaserFollowerParams(
    standstill_gap_m=0.35,
    time_gap_s=0.6,
    min_gap_m=0.15,
    comfort_decel_mps2=0.5,
    lookahead_min_m=0.3,
    trail_spacing_m=0.02,
    perception=PerceptionParams(break_abs_m=0.03, corner_abs_m=0.01),
    tracker=TrackerParams(
        accel_noise_mps2=1.0,
        meas_noise_m=0.01,
        start_range_max_m=1.5,
        start_lateral_m=0.2,
        init_speed_std_mps=0.3,
    ),
    fallback=RouteFollowingParams(lookahead_min_m=0.3, comfort_decel_mps2=0.5),
)


def straight_path(
    length_m: float = 2000.0, y_m: float = 0.0, spacing_m: float = 0.5, lane_width_m: float = 3.2
) -> RoutePath:
    n = int(length_m / spacing_m) + 1
    pts = np.column_stack([np.linspace(-50.0, length_m - 50.0, n), np.full(n, y_m)])
    return RoutePath.from_pieces([pts], ["e_0"], [13.89], [lane_width_m], spacing_m)


def arc_path(radius_m: float, spacing_m: float = 0.5, lane_width_m: float = 3.2) -> RoutePath:
    """Straight along +x up to x = 0, then a left curve of `radius_m` (centre (0, R))."""
    back = np.column_stack([np.linspace(-50.0, 0.0, 101), np.zeros(101)])
    phi = np.linspace(0.0, math.pi, 400)
    arc = np.column_stack([radius_m * np.sin(phi), radius_m * (1.0 - np.cos(phi))])
    return RoutePath.from_pieces(
        [back, arc], ["e_0", "e_1"], [13.89] * 2, [lane_width_m] * 2, spacing_m
    )


@dataclass
class Vehicle:
    """A vehicle of the scripted world: model state and shape (reference = rear axle)."""

    x: float
    y: float
    yaw: float
    v: float
    front_m: float
    length_m: float
    width_m: float

    @property
    def bumper(self) -> tuple[float, float]:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return self.x + self.front_m * c, self.y + self.front_m * s

    @property
    def rear(self) -> tuple[float, float]:
        back = self.length_m - self.front_m
        return self.x - back * math.cos(self.yaw), self.y - back * math.sin(self.yaw)

    @property
    def rect(self) -> list[float]:
        mid = self.front_m - 0.5 * self.length_m
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return [self.x + mid * c, self.y + mid * s, self.yaw, self.length_m, self.width_m]

    def move(self, model, speed: float, yaw_rate: float, limits: MotionLimits, dt: float) -> None:
        st = KinematicState.of(self.x, self.y, self.yaw, self.v)
        st = model.step(st, np.array([speed]), np.array([yaw_rate]), limits, dt)
        self.x, self.y = float(st.x_m[0]), float(st.y_m[0])
        self.yaw, self.v = float(st.yaw_rad[0]), float(st.speed_mps[0])


def car(x: float, y: float = 0.0, yaw: float = 0.0, v: float = 0.0) -> Vehicle:
    return Vehicle(x, y, yaw, v, CAR_FRONT, CAR_LEN, CAR_WIDTH)


def robot(x: float, y: float = 0.0, yaw: float = 0.0, v: float = 0.0) -> Vehicle:
    return Vehicle(x, y, yaw, v, ROBOT_FRONT, ROBOT_LEN, ROBOT_WIDTH)


def observe(
    me: Vehicle,
    t: float,
    dt: float,
    laser: LaserConfig,
    limits: MotionLimits,
    path: RoutePath,
    rects: list[list[float]],
    segments: list[list[float]] | None = None,
    rng: np.random.Generator | None = None,
    lane_offset_m: float = 0.0,
) -> Observation:
    origin = me.bumper
    ranges = cast_rays(origin, me.yaw, laser, rects or None, segments, rng)
    scan = LaserScan.from_ranges(laser, ranges, origin, me.yaw, t)
    return Observation(
        time_s=t,
        dt_s=dt,
        vehicle_id="f",
        role="follower",
        x_m=me.x,
        y_m=me.y,
        yaw_rad=me.yaw,
        speed_mps=me.v,
        front_offset_m=me.front_m,
        length_m=me.length_m,
        width_m=me.width_m,
        limits=limits,
        path=path,
        lane_offset_m=lane_offset_m,
        scan=scan,
    )


Script = Callable[[float, Vehicle], tuple[float, float]]
"""(time, predecessor) -> (speed command, yaw-rate command) of the predecessor."""


@dataclass
class Run:
    gap: list[float] = field(default_factory=list)
    """True bumper-to-rear gap (straight line) per step."""
    desired: list[float] = field(default_factory=list)
    speed: list[float] = field(default_factory=list)
    lead_speed: list[float] = field(default_factory=list)
    lead_xy: list[tuple[float, float]] = field(default_factory=list)
    own_xy: list[tuple[float, float]] = field(default_factory=list)
    in_view: list[bool] = field(default_factory=list)
    mode: list[str] = field(default_factory=list)
    collided: bool = False

    def arrays(self, name: str) -> np.ndarray:
        return np.asarray(getattr(self, name), dtype=np.float64)


def closed_loop(
    ctrl: LaserFollower,
    lead: Vehicle,
    me: Vehicle,
    script: Script,
    steps: int,
    dt: float,
    laser: LaserConfig,
    limits: MotionLimits,
    model,
    path: RoutePath,
    visible: Callable[[float], bool] = lambda t: True,
    seed: int = 0,
) -> Run:
    rng = np.random.default_rng(seed)
    run = Run()
    ctrl.reset()
    for k in range(steps):
        t = k * dt
        rects = [lead.rect] if visible(t) else []
        obs = observe(me, t, dt, laser, limits, path, rects, rng=rng)
        cmd = ctrl.step(obs)
        assert obs.vehicle_ahead is None
        lead_cmd = script(t, lead)
        lead.move(model, lead_cmd[0], lead_cmd[1], limits, dt)
        me.move(model, cmd.speed_mps, cmd.yaw_rate_radps, limits, dt)
        run.gap.append(math.dist(me.bumper, lead.rear))
        run.desired.append(ctrl.desired_gap_m(me.v))
        run.speed.append(me.v)
        run.lead_speed.append(lead.v)
        run.lead_xy.append((lead.x, lead.y))
        run.own_xy.append((me.x, me.y))
        run.in_view.append(ctrl.track is not None and ctrl.track.in_view)
        run.mode.append(ctrl.mode)
        if visible(t) and rectangles_overlap(np.array([lead.rect]), np.array([me.rect]))[0]:
            run.collided = True
    return run


def deviation_from_path(points: np.ndarray, path_points: np.ndarray) -> np.ndarray:
    """Distance of each point to the polyline through path_points."""
    a, b = path_points[:-1], path_points[1:]
    d = b - a
    len2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    out = np.empty(len(points))
    for i, p in enumerate(points):
        t = np.clip(np.einsum("ij,ij->i", p - a, d) / len2, 0.0, 1.0)
        out[i] = np.min(np.hypot(*(a + d * t[:, None] - p).T))
    return out


# ----------------------------------------------------------------------------- params, API


def test_registered_with_car_defaults_and_strict_params():
    assert CONTROLLERS.get("laser_follower") is LaserFollower
    p = LaserFollowerParams()
    assert p.policy == "constant_time_gap" and p.on_lost == "stop"
    ctrl = LaserFollower(p)
    assert ctrl.desired_gap_m(0.0) == pytest.approx(2.5)
    assert ctrl.desired_gap_m(10.0) == pytest.approx(12.5)
    const = LaserFollower(LaserFollowerParams(policy="constant_distance", standstill_gap_m=8.0))
    assert const.desired_gap_m(13.0) == pytest.approx(8.0)
    assert ctrl.track is None
    loaded = load_dataclass(
        LaserFollowerParams,
        {"on_lost": "route_following", "tracker": {"max_missed_scans": 4}},
        "s.yaml",
        "params",
    )
    assert loaded.on_lost == "route_following" and loaded.tracker.max_missed_scans == 4
    with pytest.raises(ScenarioError, match="on_lost"):
        load_dataclass(LaserFollowerParams, {"on_lost": "stopp"}, "s.yaml", "params")
    with pytest.raises(ScenarioError, match="time_gap_s"):
        load_dataclass(LaserFollowerParams, {"time_gap_s": -1.0}, "s.yaml", "params")
    with pytest.raises(ScenarioError, match=r"perception\.min_points"):
        load_dataclass(LaserFollowerParams, {"perception": {"min_points": 1}}, "s.yaml", "params")


# ----------------------------------------------------------------------------- open loop


def open_loop(lead_rects, me: Vehicle, steps=15, dt=0.1, params=None, segments=None, lead_v=0.0):
    """Feed a few scans of static (or uniformly moving along x) boxes; last command."""
    ctrl = LaserFollower(params or LaserFollowerParams())
    ctrl.reset()
    path = straight_path()
    rng = np.random.default_rng(1)
    cmd = None
    for k in range(steps):
        rects = [[r[0] + lead_v * k * dt, *r[1:]] for r in lead_rects]
        obs = observe(me, k * dt, dt, CAR_LASER, CAR_LIMITS, path, rects, segments, rng)
        cmd = ctrl.step(obs)
    assert cmd is not None
    return ctrl, cmd


@pytest.mark.slow
def test_predecessor_straight_ahead_is_tracked_and_followed():
    me = car(0.0, v=10.0)
    lead = car(CAR_FRONT + 12.0 + (CAR_LEN - CAR_FRONT), v=10.0)  # rear 12 m ahead of bumper
    ctrl, cmd = open_loop([lead.rect], me, lead_v=10.0)
    tr = ctrl.track
    assert tr is not None and tr.in_view
    # the last scan is the 15th: the lead moved 14 m but `me` did not (open loop)
    assert tr.range_m == pytest.approx(12.0 + 14.0, abs=0.1)
    assert abs(tr.bearing_rad) < 0.01
    assert tr.range_rate_mps == pytest.approx(0.0, abs=1.0)  # lead 10 m/s, me reported 10 m/s
    assert tr.speed_mps == pytest.approx(10.0, abs=1.0)
    assert abs(cmd.yaw_rate_radps) < 0.02


def test_offset_predecessor_steers_towards_it():
    me = car(0.0, v=5.0)
    lead = car(CAR_FRONT + 10.0 + 0.9, y=1.0)  # rear 10 m ahead, 1 m to the left
    ctrl, cmd = open_loop([lead.rect], me)
    tr = ctrl.track
    assert tr is not None
    assert tr.bearing_rad == pytest.approx(math.atan2(1.0, 10.0), abs=0.01)
    assert cmd.yaw_rate_radps > 0.0
    right = car(CAR_FRONT + 10.0 + 0.9, y=-1.0)
    _, cmd_r = open_loop([right.rect], me)
    assert cmd_r.yaw_rate_radps < 0.0


def test_turning_predecessor_keeps_its_rear_centre():
    me = car(0.0, v=5.0)
    yaw = 0.5
    rear = np.array([CAR_FRONT + 9.0, 1.0])
    back = CAR_LEN - CAR_FRONT
    lead = car(rear[0] + back * math.cos(yaw), rear[1] + back * math.sin(yaw), yaw)
    ctrl, cmd = open_loop([lead.rect], me)
    tr = ctrl.track
    assert tr is not None
    assert math.hypot(tr.x_m - rear[0], tr.y_m - rear[1]) < 0.1
    assert cmd.yaw_rate_radps > 0.0


def test_partially_occluded_predecessor_is_tracked_at_its_true_rear():
    me = car(0.0, v=5.0)
    lead = car(CAR_FRONT + 15.0 + 0.9)
    # a parked car on the left hides the left part of the lead's rear
    parked = car(CAR_FRONT + 6.0 + 0.9, y=1.9)
    # and a wall on the right beyond the lead
    wall = [[CAR_FRONT, -4.0, CAR_FRONT + 60.0, -4.0]]
    ctrl, _ = open_loop([lead.rect, parked.rect], me, segments=wall)
    tr = ctrl.track
    assert tr is not None and tr.in_view
    assert math.hypot(tr.x_m - lead.rear[0], tr.y_m - lead.rear[1]) < 0.1


def test_absent_predecessor_stops_or_falls_back_to_the_route():
    me = car(0.0, v=10.0)
    ctrl, cmd = open_loop([], me, steps=3)
    assert ctrl.track is None and ctrl.mode == "stopping"
    assert cmd.speed_mps == pytest.approx(10.0 - 2.5 * 0.1)  # comfortable decel
    fb = LaserFollowerParams(on_lost="route_following")
    ctrl, cmd = open_loop([], car(0.0, y=1.0, v=10.0), steps=3, params=fb)
    assert ctrl.mode == "route_following"
    assert cmd.speed_mps > 10.0 and cmd.yaw_rate_radps < 0.0  # accelerates, steers to y = 0


def test_too_close_predecessor_brakes_hard_and_very_close_stops():
    me = car(0.0, v=10.0)
    lead = car(CAR_FRONT + 4.0 + 0.9)  # stopped, 4 m ahead at 10 m/s
    ctrl, cmd = open_loop([lead.rect], me, steps=4)
    assert ctrl.mode == "following"
    assert cmd.speed_mps <= 10.0 - 0.7 * CAR_LIMITS.max_decel_mps2 * 0.1
    lead = car(CAR_FRONT + 0.6 + 0.9)  # within min_gap_m
    _, cmd = open_loop([lead.rect], car(0.0, v=1.0), steps=1)
    assert cmd.speed_mps == 0.0
    # closer than the robot scanner's range_min (0.3 m): -inf readings, stop
    ctrl = LaserFollower(ROBOT_PARAMS)
    me = robot(0.0, v=0.3)
    obs = observe(
        me, 0.0, 0.05, ROBOT_LASER, ROBOT_LIMITS, straight_path(), [robot(0.2 + 0.15).rect],
        rng=np.random.default_rng(0),
    )  # fmt: skip
    assert obs.scan is not None and np.isneginf(obs.scan.ranges).any()
    assert ctrl.step(obs).speed_mps == 0.0


def test_wall_ahead_is_not_taken_for_a_predecessor():
    me = car(0.0, v=5.0)
    wall = [[CAR_FRONT + 20.0, -10.0, CAR_FRONT + 20.0, 10.0]]
    ctrl, _ = open_loop([], me, segments=wall)
    assert ctrl.track is None


def test_stale_scan_is_not_processed_twice_and_reset_forgets():
    me = car(0.0, v=5.0)
    lead = car(CAR_FRONT + 10.9)
    ctrl = LaserFollower()
    rng = np.random.default_rng(2)
    obs = observe(me, 0.0, 0.1, CAR_LASER, CAR_LIMITS, straight_path(), [lead.rect], rng=rng)
    for k in range(5):  # the same scan object, five steps: one hit only
        ctrl.step(Observation(**{**obs.__dict__, "time_s": 0.1 * k}))
    assert ctrl.tracker.hits == 1 and ctrl.track is None
    ctrl.reset()
    assert not ctrl.tracker.active and len(ctrl.trail) == 0


# ----------------------------------------------------------------------------- closed loop


def car_loop(ctrl, lead, me, script, steps, path=None, visible=lambda t: True):
    return closed_loop(
        ctrl,
        lead,
        me,
        script,
        steps,
        0.1,
        CAR_LASER,
        CAR_LIMITS,
        Bicycle(),
        path or straight_path(),
        visible,
    )


def test_car_hard_brake_to_standstill_no_collision():
    """(a) 14 m/s in equilibrium, then the predecessor brakes at 7.5 m/s^2 to a stop."""
    ctrl = LaserFollower()
    v0 = 14.0
    gap0 = ctrl.desired_gap_m(v0) + 3.0  # starts 3 m off the desired gap
    me = car(0.0, v=v0)
    lead = car(CAR_FRONT + gap0 + (CAR_LEN - CAR_FRONT), v=v0)

    def script(t, veh):
        return (v0, 0.0) if t < 20.0 else (0.0, 0.0)

    run = car_loop(ctrl, lead, me, script, 400, visible=lambda t: True)
    gap, desired = run.arrays("gap"), run.arrays("desired")
    assert not run.collided and gap.min() > 0.5
    err = gap - desired
    before = slice(150, 200)  # 15..20 s: spacing error converged while cruising
    assert np.abs(err[before]).max() < 0.3
    assert run.speed[-1] < 0.05
    assert gap[-1] == pytest.approx(2.5, abs=0.5)  # ends near standstill_gap_m
    assert all(m == "following" for m in run.mode[5:])


def lead_route(
    lead: Vehicle,
    script: Script,
    steps: int,
    dt: float,
    limits: MotionLimits,
    model,
    spacing_m: float,
    lane_width_m: float,
) -> RoutePath:
    """The route the lead drives (its script dry-run on a copy): the platoon's shared route,
    straight behind the lead's start and on beyond its last position."""
    ghost = Vehicle(**lead.__dict__)
    xy = [(ghost.x - 100.0 * math.cos(ghost.yaw), ghost.y - 100.0 * math.sin(ghost.yaw))]
    for k in range(steps):
        xy.append((ghost.x, ghost.y))
        ghost.move(model, *script(k * dt, ghost), limits, dt)
    xy.append((ghost.x + 100.0 * math.cos(ghost.yaw), ghost.y + 100.0 * math.sin(ghost.yaw)))
    return RoutePath.from_pieces([np.asarray(xy)], ["e_0"], [13.89], [lane_width_m], spacing_m)


def turn_script(v: float, radius: float, start_x: float) -> Script:
    """Straight along +x, a 90 deg left turn of `radius` from x = start_x, then straight."""
    state = {"turned": 0.0}

    def script(t: float, veh: Vehicle) -> tuple[float, float]:
        if veh.x >= start_x and state["turned"] < math.pi / 2:
            state["turned"] += v / radius * 0.1
            return v, v / radius
        return v, 0.0

    return script


@pytest.mark.parametrize("steer_at", ["trail", "predecessor"])
def test_car_turn_corners_on_the_leaders_line(steer_at, request):
    """(b) 8 m/s, 90 deg turn of radius 15 m: lateral deviation from the leader's path."""
    v = 8.0
    ctrl = LaserFollower(LaserFollowerParams(steer_at=steer_at))
    gap0 = ctrl.desired_gap_m(v)
    me = car(0.0, v=v)
    lead = car(CAR_FRONT + gap0 + (CAR_LEN - CAR_FRONT), v=v)
    route = lead_route(lead, turn_script(v, 15.0, 60.0), 250, 0.1, CAR_LIMITS, Bicycle(), 0.5, 3.2)
    run = car_loop(ctrl, lead, me, turn_script(v, 15.0, 60.0), 250, path=route)
    assert not run.collided
    lead_xy, own_xy = np.asarray(run.lead_xy), np.asarray(run.own_xy)
    assert lead_xy[-1, 1] > 40.0  # the lead went round the corner and on north
    dev = deviation_from_path(own_xy, np.vstack([[[-100.0, 0.0]], lead_xy]))
    request.node.user_properties.append(("max_deviation_m", float(dev.max())))
    assert all(run.in_view[5:])
    err = run.arrays("gap") - run.arrays("desired")
    if steer_at == "trail":
        assert dev.max() < 0.5
        assert np.abs(err[20:]).max() < 1.5
    else:
        assert dev.max() > 0.5  # aiming at the current rear cuts the corner


def test_trail_follower_cuts_the_corner_less_than_direct_pursuit():
    devs = {}
    for steer_at in ("trail", "predecessor"):
        ctrl = LaserFollower(LaserFollowerParams(steer_at=steer_at))
        me = car(0.0, v=8.0)
        lead = car(CAR_FRONT + ctrl.desired_gap_m(8.0) + 0.9, v=8.0)
        script = turn_script(8.0, 15.0, 60.0)
        route = lead_route(lead, script, 250, 0.1, CAR_LIMITS, Bicycle(), 0.5, 3.2)
        run = car_loop(ctrl, lead, me, turn_script(8.0, 15.0, 60.0), 250, path=route)
        lead_xy = np.vstack([[[-100.0, 0.0]], np.asarray(run.lead_xy)])
        devs[steer_at] = deviation_from_path(np.asarray(run.own_xy), lead_xy).max()
    assert devs["trail"] < 0.5 * devs["predecessor"]


def test_robot_scale_speed_steps_and_turn_keep_in_view():
    """(c) robots, dt 0.05: 0.1 -> 0.5 m/s straight, then a 90 deg turn of radius 1 m."""
    ctrl = LaserFollower(ROBOT_PARAMS)
    me = robot(0.0, v=0.1)
    lead = robot(ROBOT_FRONT + ctrl.desired_gap_m(0.1) + 0.15, v=0.1)

    def make_script() -> Script:
        turn = turn_script(0.3, 1.0, 4.0)

        def script(t, veh):
            if veh.x < 4.0 and veh.y < 0.01:
                return (0.1 if t < 5.0 else 0.5), 0.0
            _, w = turn(t, veh)
            return 0.3, w * 0.1 / 0.05  # turn_script integrates at dt 0.1: scale to dt 0.05

        return script

    # the paper world's lanes are 0.5 m wide: the default corridor scales with them
    route = lead_route(lead, make_script(), 900, 0.05, ROBOT_LIMITS, Unicycle(), 0.05, 0.5)
    run = closed_loop(
        ctrl, lead, me, make_script(), 900, 0.05, ROBOT_LASER, ROBOT_LIMITS, Unicycle(), route
    )
    assert not run.collided
    assert all(run.in_view[5:]), "predecessor stays in view"
    gap = run.arrays("gap")
    err = gap - run.arrays("desired")
    assert gap.min() > 0.2
    lead_xy = np.asarray(run.lead_xy)
    assert lead_xy[-1, 1] > 1.5  # the lead turned north
    dev = deviation_from_path(np.asarray(run.own_xy), np.vstack([[[-1.0, 0.0]], lead_xy]))
    assert dev.max() < 0.05
    assert np.abs(err[-100:]).max() < 0.05


def test_predecessor_disappears_then_reappears():
    """(d) the lead vanishes from 10 s to 18 s (e.g. a sensor fault), then is back ahead."""

    def visible(t: float) -> bool:
        return not (10.0 <= t < 18.0)

    # on_lost = stop: a smooth stop; the lead (which stopped too) is picked up again
    def stopping_lead(t, veh):
        return (10.0 if t < 12.0 else 0.0), 0.0

    ctrl = LaserFollower()
    me = car(0.0, v=10.0)
    lead = car(CAR_FRONT + ctrl.desired_gap_m(10.0) + 0.9, v=10.0)
    run = car_loop(ctrl, lead, me, stopping_lead, 300, visible=visible)
    speed, modes = run.arrays("speed"), run.mode
    assert modes[:2] == ["stopping"] * 2  # a new track is confirmed on its 3rd scan
    lost = [k for k, m in enumerate(modes) if m == "stopping" and k > 2]
    assert lost and 100 <= lost[0] <= 112  # lost within ~1 s of vanishing
    decel = -np.diff(speed[lost[0] : lost[-1]]) / 0.1
    assert decel.max() <= 2.5 + 1e-6  # comfortable
    assert speed[lost[-1]] == pytest.approx(0.0, abs=1e-9)  # stood still before it is back
    assert 180 <= lost[-1] <= 185 and modes[-1] == "following"  # resumed
    assert not run.collided
    assert run.gap[-1] == pytest.approx(2.5, abs=0.5)  # closed up to the standstill gap

    # on_lost = route_following: follows observation.path (y = 0), then the lead again
    def cruising_lead(t, veh):
        return 10.0, 0.0

    params = LaserFollowerParams(
        on_lost="route_following", fallback=RouteFollowingParams(cruise_speed_mps=9.0)
    )
    ctrl = LaserFollower(params)
    me = car(0.0, y=0.5, v=10.0)
    lead = car(CAR_FRONT + ctrl.desired_gap_m(10.0) + 0.9, y=0.5, v=10.0)
    run = car_loop(ctrl, lead, me, cruising_lead, 300, visible=visible)
    modes = run.mode
    k_fb = modes.index("route_following", 3)
    assert 100 <= k_fb <= 112
    own = np.asarray(run.own_xy)
    assert abs(own[k_fb, 1]) > 0.4 and abs(own[179, 1]) < 0.05  # drove onto the route
    assert run.speed[179] == pytest.approx(9.0, abs=0.1)  # at the fallback's cruise speed
    k_back = len(modes) - modes[::-1].index("route_following")
    assert 180 <= k_back <= 185 and modes[-1] == "following"  # resumed
    assert not run.collided
    err = run.arrays("gap") - run.arrays("desired")
    assert abs(err[-1]) < abs(err[k_back])  # closing the spacing error again


# ----------------------------------------------------------------------------- route corridor


def rear_track(ref_xy: np.ndarray, back_m: float) -> np.ndarray:
    """Rear-centre positions of a vehicle from its reference-point track (heading from it)."""
    step = np.diff(ref_xy, axis=0)
    yaw = np.concatenate([[0.0], np.arctan2(step[:, 1], step[:, 0])])
    return ref_xy - back_m * np.column_stack([np.cos(yaw), np.sin(yaw)])


def car_with_rear(rear_x: float, rear_y: float, yaw: float = 0.0, v: float = 0.0) -> Vehicle:
    back = CAR_LEN - CAR_FRONT
    return car(rear_x + back * math.cos(yaw), rear_y + back * math.sin(yaw), yaw, v)


def test_corridor_params_are_checked():
    p = LaserFollowerParams()
    assert p.corridor_half_width_m == "lane" and p.corridor_exit_s > 0.0
    loaded = load_dataclass(LaserFollowerParams, {"corridor_half_width_m": 2.0}, "s.yaml", "params")
    assert loaded.corridor_half_width_m == 2.0
    off = load_dataclass(LaserFollowerParams, {"corridor_half_width_m": None}, "s.yaml", "params")
    assert off.corridor_half_width_m is None
    for bad in (0.0, "lanes"):
        with pytest.raises(ScenarioError, match="corridor_half_width_m"):
            load_dataclass(LaserFollowerParams, {"corridor_half_width_m": bad}, "s.yaml", "params")
    with pytest.raises(ScenarioError, match="corridor_exit_s"):
        load_dataclass(LaserFollowerParams, {"corridor_exit_s": -0.1}, "s.yaml", "params")


def corridor_open_loop(
    rects, me: Vehicle, path: RoutePath, params: LaserFollowerParams, steps=10, lane_offset_m=0.0
):
    ctrl = LaserFollower(params)
    rng = np.random.default_rng(4)
    cmd = None
    for k in range(steps):
        obs = observe(
            me, k * 0.1, 0.1, CAR_LASER, CAR_LIMITS, path, rects, rng=rng,
            lane_offset_m=lane_offset_m,
        )  # fmt: skip
        cmd = ctrl.step(obs)
    assert cmd is not None
    return ctrl, cmd


@pytest.mark.parametrize("corridor", ["lane", None])
def test_car_in_the_neighbouring_lane_is_not_taken_for_a_predecessor(corridor):
    """(a) predecessor lost, route following: a car one lane to the left, slightly ahead,
    inside a (widened) start gate, is not tracked; without the corridor it would be."""
    params = LaserFollowerParams(
        on_lost="route_following",
        corridor_half_width_m=corridor,
        tracker=TrackerParams(start_lateral_m=4.0),
    )
    neighbour = car_with_rear(CAR_FRONT + 4.0, 3.2)
    ctrl, _ = corridor_open_loop([neighbour.rect], car(0.0, v=8.0), straight_path(), params)
    if corridor is None:
        assert ctrl.mode == "following"  # the bug: it would follow the neighbour
        return
    assert ctrl.mode == "route_following" and ctrl.track is None
    assert not ctrl.tracker.active
    # a car in the own lane further ahead is still picked up, the neighbour is not
    own = car_with_rear(CAR_FRONT + 20.0, 0.2)
    ctrl, _ = corridor_open_loop(
        [neighbour.rect, own.rect], car(0.0, v=8.0), straight_path(), params
    )
    assert ctrl.mode == "following" and ctrl.track is not None
    assert math.hypot(ctrl.track.x_m - own.rear[0], ctrl.track.y_m - own.rear[1]) < 0.2


def test_corridor_follows_the_lane_sumo_drives_in_beside_the_route():
    """With `actuation: lane` SUMO may drive the platoon one lane left of the route's
    own lane: the corridor is centred on that lane (`lane_offset_m`), so the predecessor
    ahead in it is followed and a car in the route's own lane is not."""
    params = LaserFollowerParams(
        on_lost="route_following", tracker=TrackerParams(start_lateral_m=4.0)
    )
    me = car(0.0, y=3.2, v=8.0)
    ahead_in_my_lane = car_with_rear(CAR_FRONT + 12.0, 3.3)
    in_route_lane = car_with_rear(CAR_FRONT + 5.0, 0.0)
    rects = [ahead_in_my_lane.rect, in_route_lane.rect]
    ctrl, _ = corridor_open_loop(rects, me, straight_path(), params, lane_offset_m=3.2)
    assert ctrl.mode == "following" and ctrl.track is not None
    rear = ahead_in_my_lane.rear
    assert math.hypot(ctrl.track.x_m - rear[0], ctrl.track.y_m - rear[1]) < 0.2
    # measured from the route's own lane, the same predecessor is outside the corridor
    ctrl, _ = corridor_open_loop([ahead_in_my_lane.rect], me, straight_path(), params)
    assert ctrl.mode == "route_following" and ctrl.track is None


@pytest.mark.parametrize(("pred_y", "lane_change"), [(3.3, 1), (-3.1, -1), (1.0, 0), (0.1, 0)])
def test_predecessor_in_the_next_lane_asks_for_a_lane_change(pred_y, lane_change):
    """Where SUMO steers, the follower asks to move to the lane its predecessor is seen
    in (more than half a lane beside the own one) and otherwise keeps its lane: a
    request SUMO's strategic lane change does not override, so SUMO's strategy does
    not take it out of its platoon's lane."""
    params = LaserFollowerParams(on_lost="route_following", corridor_margin_rel=1.2)
    me = car(0.0, v=8.0)
    start = car_with_rear(CAR_FRONT + 10.0, 0.0)
    ctrl = LaserFollower(params)
    rng = np.random.default_rng(4)
    cmd = None
    for k in range(20):  # acquired straight ahead, then it moves over
        pred = start if k < 10 else car_with_rear(CAR_FRONT + 10.0, pred_y)
        obs = observe(me, k * 0.1, 0.1, CAR_LASER, CAR_LIMITS, straight_path(), [pred.rect],
                      rng=rng)  # fmt: skip
        cmd = ctrl.step(obs)
    assert cmd is not None and ctrl.mode == "following"
    assert cmd.lane_change == lane_change
    assert cmd.keep_lane == (lane_change == 0)


@pytest.mark.parametrize("corridor", ["lane", None])
def test_car_in_the_outer_lane_of_a_curve_is_not_taken_for_a_predecessor(corridor):
    """(a) at the start of a left curve (radius 60 m) a car in the outer lane 20 m on
    appears straight ahead (inside the default start gate); the own lane is empty."""
    radius, lane = 60.0, 3.2
    phi = 20.0 / radius
    outer = radius + lane
    rear = (outer * math.sin(phi), radius - outer * math.cos(phi))
    neighbour = car_with_rear(*rear, yaw=phi)
    assert abs(rear[1]) < 0.5  # straight ahead of the follower
    params = LaserFollowerParams(on_lost="route_following", corridor_half_width_m=corridor)
    ctrl, cmd = corridor_open_loop(
        [neighbour.rect], car(-CAR_FRONT, v=8.0), arc_path(radius), params
    )
    if corridor is None:
        assert ctrl.mode == "following"
        return
    assert ctrl.mode == "route_following" and ctrl.track is None
    assert cmd.yaw_rate_radps > 0.0  # on along the own (left-curving) route


@pytest.mark.parametrize("exit_s", [0.5, 1000.0])
def test_predecessor_turning_off_the_route_is_dropped_and_not_followed(exit_s):
    """(b) the route goes straight on; the tracked predecessor turns left (radius 15 m).

    Default ``corridor_exit_s``: the track is dropped within that time after the rear
    left the corridor and the follower goes on along its route (fallback). With an
    exit time that never expires the track is kept, but the steering still keeps the
    follower on its route: trail points outside the corridor are not followed.
    """
    v = 8.0
    params = LaserFollowerParams(
        on_lost="route_following",
        corridor_exit_s=exit_s,
        fallback=RouteFollowingParams(cruise_speed_mps=v),
    )
    ctrl = LaserFollower(params)
    me = car(0.0, v=v)
    lead = car(CAR_FRONT + ctrl.desired_gap_m(v) + (CAR_LEN - CAR_FRONT), v=v)
    steps = 160
    path = straight_path()
    run = car_loop(ctrl, lead, me, turn_script(v, 15.0, 60.0), steps, path=path)
    assert not run.collided
    modes = run.mode
    assert all(m == "following" for m in modes[3:50])  # before the turn
    lead_xy = np.asarray(run.lead_xy)
    rear_y = rear_track(lead_xy, CAR_LEN - CAR_FRONT)[:, 1]
    half_width = (0.5 + params.corridor_margin_rel) * 3.2
    k_out = int(np.argmax(np.abs(rear_y) > half_width))
    assert k_out > 50 and lead_xy[-1, 1] > 40.0  # the lead left the route, went north
    own = np.asarray(run.own_xy)
    assert np.abs(own[:, 1]).max() < 0.5 * 3.2  # never more than half a lane off the route
    assert own[-1, 0] > 100.0  # and went on straight past the junction (x = 60..75)
    if exit_s < 100.0:
        k_lost = modes.index("route_following", 3)
        # dropped within corridor_exit_s (+ a scan, + the filter lagging the true rear)
        assert k_out - 2 <= k_lost <= k_out + round(exit_s / 0.1) + 3
        assert all(m == "route_following" for m in modes[k_lost:])  # not picked up again
        assert run.speed[-1] == pytest.approx(v, abs=0.2)
        assert np.abs(own[k_lost:, 1]).max() < 0.1
    else:
        assert all(m == "following" for m in modes[3:100])  # until it is out of sight
        # the trail stops at the corridor's edge
        assert np.abs(ctrl.trail[:, 1]).max() <= half_width


def test_robot_predecessor_turning_off_the_route_is_dropped():
    """(b) at robot scale: 0.5 m lanes (paper world), a 90 deg left turn of radius 1 m."""
    ctrl = LaserFollower(replace(ROBOT_PARAMS, on_lost="route_following"))
    v = 0.3
    me = robot(0.0, v=v)
    lead = robot(ROBOT_FRONT + ctrl.desired_gap_m(v) + 0.15, v=v)
    turn = turn_script(v, 1.0, 2.0)

    def script(t, veh):
        _, w = turn(t, veh)
        return v, w * 0.1 / 0.05

    run = closed_loop(
        ctrl, lead, me, script, 400, 0.05, ROBOT_LASER, ROBOT_LIMITS, Unicycle(),
        straight_path(spacing_m=0.05, lane_width_m=0.5),
    )  # fmt: skip
    assert not run.collided
    modes = run.mode
    assert all(m == "following" for m in modes[5:100])
    k_lost = modes.index("route_following", 5)
    assert all(m == "route_following" for m in modes[k_lost:])
    lead_xy = np.asarray(run.lead_xy)
    assert lead_xy[-1, 1] > 1.5
    rear_y = rear_track(lead_xy, ROBOT_LEN - ROBOT_FRONT)[:, 1]
    k_out = int(np.argmax(np.abs(rear_y) > (0.5 + 0.2) * 0.5))  # the corridor: 0.35 m
    assert k_out > 100
    assert k_out - 2 <= k_lost <= k_out + round(0.5 / 0.05) + 4
    own = np.asarray(run.own_xy)
    assert np.abs(own[:, 1]).max() < 0.25 and own[-1, 0] > 3.5
