"""REFERENCE ONLY (test oracle): ``platoon_sumo/control/laser_follower.py`` as it was
before the fast path, kept so the equivalence tests and ``tools/bench_controllers.py``
can replay recorded observations through it. Changes from the original: it imports the
reference perception (``reference_perception.py``), uses the reference route-path
look-ups (``reference_path.py``) instead of ``RoutePath``'s methods, its route-following
fallback is the reference one (``reference_route_following.py``: ``RouteFollowing`` as it
was before its step became a kernel), and it is not registered as a controller. Do not
use in package code, do not change.

Laser-only follower: tracks the predecessor's rear in the scan and drives on its path.

No communication and no SUMO ground truth: the controller reads its own pose and speed
(odometry), its laser scan, ``dt`` and its limits. ``observation.path`` (its own route,
which any car knows) is the map of where it may drive: the route corridor below and the
``route_following`` fallback while the predecessor is lost. ``observation.vehicle_ahead``
is never read.

Each step:

1. **Perception** (on a new scan only, see ``perception.py``): segment the scan, fit
   vehicle rears, associate the one nearest the predicted rear (Mahalanobis gate) or,
   without a track, start one on the rear closest to straight ahead in the start gate;
   a constant-velocity Kalman filter in the world (odometry) frame gives the
   predecessor's rear position and velocity.
   **Route corridor** (``corridor_half_width_m``, on by default): a rear counts as on
   the route when, projected onto ``observation.path`` near the follower's own arc
   length, it lies ahead and within the corridor half-width of the centre-line of the
   lane the follower drives in (the route's own, or ``observation.lane_offset_m``
   beside it when SUMO picks the lane; default half-width: half the lane width there
   plus ``corridor_margin_rel`` lane widths). A
   track starts only on such a rear (not on a car in the neighbouring lane), and a
   track whose rear stays outside the corridor for more than ``corridor_exit_s`` is
   dropped (the predecessor turned off the route: lost, see 5.) instead of being
   followed off the route.
2. **Trail**: the filtered rear positions are appended to a trail every
   ``trail_spacing_m`` (only inside the route corridor); points behind the follower are
   dropped.
3. **Longitudinal**: gap = distance from the own front bumper to the predecessor's rear,
   ``a = k_gap (gap - desired_gap_m(v)) + k_rate * range_rate``, integrated to a speed
   command, capped by a Krauss-style safe speed (can still stop ``min_gap_m`` short if
   the predecessor brakes) and a hard stop when anything is within ``min_gap_m`` of the
   bumper (or closer than the scanner's ``range_min``) in front of the vehicle.
4. **Lateral**: pure pursuit of the reference point on the trail (the platoon corners
   on the leader's line); ``steer_at="predecessor"`` aims at the predecessor's current
   rear instead (what a naive follower does; it cuts corners) for comparison. While the
   rear is outside the route corridor the steering never aims at it: the trail (inside
   the corridor) is followed and, once it is used up, the own route. Where SUMO steers
   (``actuation: lane``) the same intent becomes a lane request: a predecessor seen
   more than half a lane beside the own lane asks SUMO for the change towards it (the
   platoon follows its leader's lane changes; widen ``corridor_margin_rel`` to about 1.2
   so a predecessor one lane over stays tracked meanwhile).
5. **Lost** (no confirmed track): ``on_lost="stop"`` brakes at ``comfort_decel_mps2``
   while steering along what is left of the trail; ``on_lost="route_following"`` hands
   over to a ``RouteFollowing`` on ``observation.path`` (without ``vehicle_ahead``, its
   speed capped by the laser's clearance along the commanded arc) until a predecessor
   is confirmed again, then follows again.

Defaults are for cars (4.5 x 1.8 m, utm30lx, up to 14 m/s, dt 0.1 s). Robot scale
(0.3 x 0.25 m, paper_follower-like scans 0.3..1-3 m, 0.1..1 m/s, dt 0.05 s)::

    LaserFollowerParams(
        standstill_gap_m=0.35, time_gap_s=0.6, min_gap_m=0.15, comfort_decel_mps2=0.5,
        lookahead_min_m=0.3, trail_spacing_m=0.02,
        perception=PerceptionParams(break_abs_m=0.03, corner_abs_m=0.01),
        tracker=TrackerParams(accel_noise_mps2=1.0, meas_noise_m=0.01,
                              start_range_max_m=1.5, start_lateral_m=0.2,
                              init_speed_std_mps=0.3),
        fallback=RouteFollowingParams(lookahead_min_m=0.3, comfort_decel_mps2=0.5,
                                      cruise_speed_mps=0.3))
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import ClassVar, Literal

import numpy as np

from platoon_sumo.config_loader import require, require_choice, require_positive
from platoon_sumo.control.base import Command, GapPolicy, Observation, Telemetry
from platoon_sumo.control.perception import PerceptionParams, TrackerParams
from platoon_sumo.control.route_following import RouteFollowingParams
from platoon_sumo.path import FloatArray, PathPoint, RoutePath
from platoon_sumo.sensors.laser import LaserScan
from tests.control.reference_path import lane_step, point_at, project
from tests.control.reference_perception import RearTracker, SensorPose, detect_rears
from tests.control.reference_route_following import ReferenceRouteFollowing

_POLICIES = ("constant_distance", "constant_time_gap")
_ON_LOST = ("stop", "route_following")
_STEER_AT = ("trail", "predecessor")
_CORRIDOR_AHEAD_LENGTHS = 3.0
"""The route is searched up to this many own vehicle lengths beyond a rear's distance."""


@dataclass(frozen=True)
class LaserFollowerParams:
    """Laser follower; defaults for cars, robot values in brackets (see the module doc)."""

    policy: Literal["constant_distance", "constant_time_gap"] = "constant_time_gap"
    """Spacing policy: gap = standstill_gap_m (+ time_gap_s * speed for a time gap)."""
    standstill_gap_m: float = 2.5
    """Bumper-to-rear gap at standstill, or always with constant_distance [m] (robots 0.35)."""
    time_gap_s: float = 1.0
    """Time gap of the constant_time_gap policy [s] (robots 0.6)."""
    k_gap_1ps2: float = 0.3
    """Acceleration per metre of gap error [1/s^2] (robots 0.3-1)."""
    k_rate_1ps: float = 0.8
    """Acceleration per m/s of range rate [1/s] (robots 0.8-1.5)."""
    min_gap_m: float = 1.0
    """Hard floor: full stop when anything is this close ahead; safe speed keeps it [m]
    (robots 0.15)."""
    comfort_decel_mps2: float = 2.5
    """Deceleration of the safe-speed term and of the stop when lost [m/s^2] (robots 0.5)."""
    reaction_time_s: float = 0.5
    """Reaction time of the Krauss-style safe speed [s]."""
    lookahead_min_m: float = 4.0
    """Shortest pure-pursuit look-ahead [m] (robots 0.3)."""
    lookahead_time_s: float = 0.5
    """Look-ahead = max(lookahead_min_m, lookahead_time_s * speed) [s]."""
    trail_spacing_m: float = 0.5
    """Distance between stored trail points [m] (robots 0.02)."""
    max_trail_points: int = 4000
    """Oldest trail points are dropped beyond this many."""
    steer_at: Literal["trail", "predecessor"] = "trail"
    """Pure pursuit on the predecessor's trail, or straight at its current rear."""
    on_lost: Literal["stop", "route_following"] = "stop"
    """What to do without a predecessor: stop comfortably, or follow the own route."""
    predecessor_width_m: float | None = None
    """Expected rear width of the predecessor [m]; None: the follower's own width."""
    corridor_half_width_m: float | Literal["lane"] | None = "lane"
    """Half-width of the own route's corridor in which a predecessor is tracked and its
    trail followed [m]; "lane": half the lane width at the rear's point of the route plus
    ``corridor_margin_rel`` lane widths (scales with the network: cars and robots);
    None: no corridor (any vehicle in the start gate, followed anywhere)."""
    corridor_margin_rel: float = 0.2
    """Margin of the "lane" corridor beyond half the lane width, in lane widths
    (3.2 m lanes: 2.24 m half-width; the paper world's 0.5 m lanes: 0.35 m)."""
    corridor_exit_s: float = 0.5
    """A track whose rear stays outside the corridor longer than this is dropped [s]."""
    perception: PerceptionParams = field(default_factory=PerceptionParams)
    tracker: TrackerParams = field(default_factory=TrackerParams)
    fallback: RouteFollowingParams = field(default_factory=RouteFollowingParams)
    """Route following used by on_lost="route_following"."""

    def __post_init__(self) -> None:
        require_choice(self.policy, _POLICIES, "policy")
        require_choice(self.on_lost, _ON_LOST, "on_lost")
        require_choice(self.steer_at, _STEER_AT, "steer_at")
        require_positive(
            self, "k_gap_1ps2", "comfort_decel_mps2", "lookahead_min_m", "trail_spacing_m"
        )
        require_positive(
            self,
            "standstill_gap_m",
            "time_gap_s",
            "k_rate_1ps",
            "min_gap_m",
            "reaction_time_s",
            "lookahead_time_s",
            "corridor_margin_rel",
            "corridor_exit_s",
            allow_zero=True,
        )
        require(self.max_trail_points >= 2, "max_trail_points", "must be >= 2")
        require(
            self.predecessor_width_m is None or self.predecessor_width_m > 0,
            "predecessor_width_m",
            "must be > 0",
        )
        hw = self.corridor_half_width_m
        require(
            hw is None or hw == "lane" or (not isinstance(hw, str) and hw > 0),
            "corridor_half_width_m",
            'must be > 0, "lane" or null',
        )


@dataclass(frozen=True)
class TrackedPredecessor:
    """The predecessor as the follower sees it (for logging)."""

    range_m: float
    """Distance from the sensor to the centre of the predecessor's rear."""
    bearing_rad: float
    """Direction of that point in the sensor frame (CCW from the sensor's axis)."""
    range_rate_mps: float
    """Rate of change of the gap (negative while closing in)."""
    in_view: bool
    """Seen in the latest scan (False while the track coasts on its prediction)."""
    speed_mps: float
    """Estimated speed of the predecessor."""
    x_m: float
    y_m: float
    """Estimated rear centre in the world (odometry) frame."""


def _krauss_safe_speed(room_m: float, lead_speed_mps: float, decel: float, tau: float) -> float:
    """Highest speed from which the vehicle can stop within ``room_m`` behind a braking lead."""
    if room_m <= 0.0:
        return 0.0
    bt = decel * tau
    return -bt + math.sqrt(bt * bt + lead_speed_mps**2 + 2.0 * decel * room_m)


class ReferenceLaserFollower:
    """Follows the vehicle ahead with the laser only (see the module docstring)."""

    Params: ClassVar[type[LaserFollowerParams]] = LaserFollowerParams

    def __init__(self, params: LaserFollowerParams | None = None):
        self.params = params or LaserFollowerParams()
        self.tracker = RearTracker(self.params.tracker)
        self._fallback = ReferenceRouteFollowing(self.params.fallback)
        self.reset()

    # ------------------------------------------------------------------ public API

    def reset(self) -> None:
        self.tracker.reset()
        self._fallback.reset()
        self._trail: list[tuple[float, float]] = []
        self._last_scan: LaserScan | None = None
        self._sensor_pose: SensorPose | None = None
        self._mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._blocked = False
        self._in_view = False
        self._scan_points: FloatArray = np.zeros((0, 2))
        self._track: TrackedPredecessor | None = None
        self._route: RoutePath | None = None
        self._route_s: float | None = None
        self._outside_since: float | None = None
        self._measured_gap_m: float | None = None
        self.mode = "lost"

    def desired_gap_m(self, speed_mps: float) -> float:
        """The spacing policy: desired bumper-to-rear gap at a given own speed [m]."""
        p = self.params
        if p.policy == "constant_distance":
            return p.standstill_gap_m
        return p.standstill_gap_m + p.time_gap_s * max(speed_mps, 0.0)

    @property
    def track(self) -> TrackedPredecessor | None:
        """The confirmed predecessor track at the last step, or None."""
        return self._track

    @property
    def trail(self) -> FloatArray:
        """The stored trail of the predecessor's rear positions (world frame), (n, 2)."""
        return np.array(self._trail, dtype=np.float64).reshape(-1, 2)

    # ------------------------------------------------------------------ step

    def step(self, observation: Observation) -> Command:
        obs, p = observation, self.params
        if p.corridor_half_width_m is not None:
            self._locate_on_route(obs)
        if obs.scan is not None and obs.scan is not self._last_scan:
            self._perceive(obs, obs.scan)
        shadow = None
        if p.on_lost == "route_following":
            # stepped every step so it always knows where on the route the vehicle is
            shadow = self._fallback.step(replace(obs, vehicle_ahead=None))
        if self.tracker.confirmed:
            self.mode = "following"
            cmd = self._follow(obs)
        else:
            self._track = None
            if shadow is not None:
                self.mode = "route_following"
                cmd = self._guarded(obs, shadow)
            else:
                self.mode = "stopping"
                cmd = self._stop(obs)
        if self._blocked:
            cmd = Command(speed_mps=0.0, yaw_rate_radps=cmd.yaw_rate_radps)
        measured = self._measured_gap_m if self.mode == "following" else None
        return replace(cmd, telemetry=Telemetry(self.mode, measured, self.gap_policy))

    @property
    def gap_policy(self) -> GapPolicy:
        """The spacing policy as data (for the trajectory table)."""
        p = self.params
        time_gap = p.time_gap_s if p.policy == "constant_time_gap" else 0.0
        return GapPolicy(p.standstill_gap_m, time_gap)

    # ------------------------------------------------------------------ perception

    def _perceive(self, obs: Observation, scan: LaserScan) -> None:
        p = self.params
        self._last_scan = scan
        pose = SensorPose(scan.origin_x_m, scan.origin_y_m, scan.heading_rad)
        self._sensor_pose = pose
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        dx, dy = scan.origin_x_m - obs.x_m, scan.origin_y_m - obs.y_m
        self._mount = (c * dx + s * dy, -s * dx + c * dy, scan.heading_rad - obs.yaw_rad)
        width = self._width(obs)
        tracker = self.tracker
        roi = None
        if tracker.active:
            px, py = tracker.predicted(obs.time_s)[:2]
            sx, sy = pose.to_sensor(float(px), float(py))
            spread = math.sqrt(p.tracker.gate_chi2 * float(np.trace(tracker.P[:2, :2]) + 0.04))
            roi = (sx, sy, max(spread, 0.5 * width) + width)
        hint = tracker.heading_hint(scan.heading_rad) - scan.heading_rad
        candidates = detect_rears(scan, p.perception, width, hint, roi)
        was_active = tracker.active
        if not was_active:  # start only on a rear on the own route
            candidates = [
                cand
                for cand in candidates
                if self._in_corridor(obs, *pose.to_world(cand.x_m, cand.y_m))
            ]
        own_v = (obs.speed_mps * c, obs.speed_mps * s)
        hit = tracker.step(obs.time_s, candidates, pose, own_v, 0.5 * width)
        inside = tracker.active and self._in_corridor(obs, *tracker.position)
        if not tracker.active or inside:
            self._outside_since = None
        elif self._outside_since is None:
            self._outside_since = obs.time_s
        elif obs.time_s - self._outside_since > p.corridor_exit_s:
            tracker.reset()  # it turned off the route: lost, do not follow it
            self._outside_since = None
            hit = None
        self._in_view = hit is not None
        if hit is not None and not was_active:
            self._trail = []  # a new track: the old trail may belong to another vehicle
        if hit is not None and inside:
            self._append_trail(*tracker.position)
        self._blocked = self._check_blocked(scan, width)
        self._scan_points = scan.points_world()

    # ------------------------------------------------------------------ route corridor

    def _locate_on_route(self, obs: Observation) -> None:
        """Track the follower's own arc length on its route (searched near the last one)."""
        if obs.path is not self._route:
            self._route, self._route_s = obs.path, None
        window = max(4.0 * obs.length_m, 2.0 * self._lookahead(obs))
        self._route_s = project(obs.path, obs.x_m, obs.y_m, self._route_s, window).s_m

    def _ahead_on_route(self, obs: Observation, x_m: float, y_m: float) -> PathPoint | None:
        """A world point projected on the own route, or None when it is not ahead."""
        if self._route_s is None:
            return None
        path, s0 = obs.path, self._route_s
        # search from the own arc length to a few vehicle lengths beyond the point's range
        reach = 0.5 * (
            math.hypot(x_m - obs.x_m, y_m - obs.y_m) + _CORRIDOR_AHEAD_LENGTHS * obs.length_m
        )
        at = project(path, x_m, y_m, s0 + reach, reach)
        return at if at.s_m > s0 else None

    def _in_corridor(self, obs: Observation, x_m: float, y_m: float) -> bool:
        """Does the world point lie ahead on the own route, within the corridor (centred on
        the own lane)?"""
        half_width = self.params.corridor_half_width_m
        if half_width is None or self._route_s is None:
            return True
        at = self._ahead_on_route(obs, x_m, y_m)
        if at is None:
            return False
        if half_width == "lane":
            path = obs.path
            i = min(int(at.s_m // path.spacing_m), len(path.lane_width_m) - 1)
            half_width = (0.5 + self.params.corridor_margin_rel) * float(path.lane_width_m[i])
        return abs(at.lateral_offset_m - obs.lane_offset_m) <= half_width

    def _lane_request(self, obs: Observation, x_m: float, y_m: float) -> int:
        """Where SUMO steers (lane actuation): +1 / -1 towards the lane of the same road in
        which the laser sees the predecessor, else 0 (also where either is in a junction
        or the route's own lane change: lanes are compared by the map, not by offsets)."""
        at = self._ahead_on_route(obs, x_m, y_m) if self._in_view else None
        if at is None or self._route_s is None:
            return 0
        return lane_step(obs.path, self._route_s, obs.lane_offset_m, at.s_m, at.lateral_offset_m)

    def _route_target(self, obs: Observation) -> tuple[float, float] | None:
        """The own route's point one look-ahead beyond the follower (None without a corridor)."""
        if self._route_s is None:
            return None
        return point_at(obs.path, self._route_s + self._lookahead(obs))

    def _width(self, obs: Observation) -> float:
        return self.params.predecessor_width_m or obs.width_m

    def _check_blocked(self, scan: LaserScan, width: float) -> bool:
        """Anything within min_gap_m of the sensor in front of the vehicle, or closer than
        the scanner's range_min (REP 117 ``-inf``: position unknown, assume the worst)?"""
        r, a = scan.ranges, scan.angles
        half = 0.5 * width
        ok = np.isfinite(r)
        x, y = r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])
        if np.any((x > 0.0) & (x <= self.params.min_gap_m) & (np.abs(y) <= half)):
            return True
        close = a[np.isneginf(r)]
        return bool(
            np.any((np.cos(close) > 0.0) & (np.abs(scan.range_min * np.sin(close)) <= half))
        )

    def _append_trail(self, x: float, y: float) -> None:
        trail = self._trail
        spacing = self.params.trail_spacing_m
        if not trail or math.hypot(x - trail[-1][0], y - trail[-1][1]) >= spacing:
            trail.append((x, y))
            if len(trail) > self.params.max_trail_points:
                del trail[0]

    def _prune_trail(self, obs: Observation) -> None:
        """Drop the leading trail points behind the vehicle (keep one for interpolation)."""
        trail = self._trail
        if len(trail) < 2:
            return
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        pts = np.asarray(trail)
        ahead = (pts[:, 0] - obs.x_m) * c + (pts[:, 1] - obs.y_m) * s > 0.0
        first_ahead = int(np.argmax(ahead)) if ahead.any() else len(trail)
        drop = first_ahead - 1
        if drop > 0:
            del trail[:drop]

    # ------------------------------------------------------------------ following

    def _follow(self, obs: Observation) -> Command:
        p, lim = self.params, obs.limits
        est = self.tracker.predicted(obs.time_s)
        rx, ry, vx, vy = (float(v) for v in est)
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        fx, fy = obs.x_m + obs.front_offset_m * c, obs.y_m + obs.front_offset_m * s
        gap = math.hypot(rx - fx, ry - fy)
        self._measured_gap_m = gap
        ux, uy = ((rx - fx) / gap, (ry - fy) / gap) if gap > 1e-9 else (c, s)
        own_vx, own_vy = obs.speed_mps * c, obs.speed_mps * s
        range_rate = ux * (vx - own_vx) + uy * (vy - own_vy)
        lead_speed = math.hypot(vx, vy)

        # Spacing along the predecessor's path (the trail), not the chord: in a curve the
        # chord is shorter and its rate mixes in the turning, which would brake the follower.
        self._prune_trail(obs)
        if p.steer_at == "trail":
            path_gap = max(self._trail_length(obs, (rx, ry)), gap)
            gap_rate = lead_speed - obs.speed_mps
        else:
            path_gap, gap_rate = gap, range_rate
        error = path_gap - self.desired_gap_m(obs.speed_mps)
        accel = p.k_gap_1ps2 * error + p.k_rate_1ps * gap_rate
        accel = min(max(accel, -lim.max_decel_mps2), lim.max_accel_mps2)
        # Safety on the straight-line gap and the closing speed along the line of sight.
        safe = _krauss_safe_speed(
            gap - p.min_gap_m, max(ux * vx + uy * vy, 0.0), p.comfort_decel_mps2, p.reaction_time_s
        )
        speed = min(max(obs.speed_mps + accel * obs.dt_s, 0.0), safe, lim.max_speed_mps)

        end: tuple[float, float] | None = (rx, ry)
        if not self._in_corridor(obs, rx, ry):
            end = None  # turning off the route: never steer after it
        if p.steer_at == "trail":
            target = self._trail_target(obs, end, self._route_target(obs) if end is None else None)
        else:
            target = end or self._route_target(obs)
        yaw_rate = self._pursuit(obs, speed, target)

        sensor = self._current_sensor_pose(obs)
        sx, sy = sensor.to_sensor(rx, ry)
        self._track = TrackedPredecessor(
            range_m=math.hypot(sx, sy),
            bearing_rad=math.atan2(sy, sx),
            range_rate_mps=range_rate,
            in_view=self._in_view,
            speed_mps=math.hypot(vx, vy),
            x_m=rx,
            y_m=ry,
        )
        return Command(
            speed_mps=speed, yaw_rate_radps=yaw_rate, lane_change=self._lane_request(obs, rx, ry)
        )

    def _trail_length(self, obs: Observation, end: tuple[float, float]) -> float:
        """Length of the trail from the front bumper to ``end`` (the predecessor's rear)."""
        pts = np.asarray([*self._trail, end], dtype=np.float64)
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        bx, by = obs.x_m + obs.front_offset_m * c, obs.y_m + obs.front_offset_m * s
        ahead = np.flatnonzero((pts[:, 0] - bx) * c + (pts[:, 1] - by) * s > 0.0)
        first = int(ahead[0]) if ahead.size else len(pts) - 1
        rest = pts[first:]
        hop = math.hypot(rest[0, 0] - bx, rest[0, 1] - by)
        return hop + float(np.hypot(*np.diff(rest, axis=0).T).sum())

    def _current_sensor_pose(self, obs: Observation) -> SensorPose:
        mx, my, myaw = self._mount
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        return SensorPose(obs.x_m + c * mx - s * my, obs.y_m + s * mx + c * my, obs.yaw_rad + myaw)

    def _lookahead(self, obs: Observation) -> float:
        p = self.params
        return max(p.lookahead_min_m, p.lookahead_time_s * obs.speed_mps)

    def _trail_target(
        self,
        obs: Observation,
        end: tuple[float, float] | None,
        beyond_trail: tuple[float, float] | None = None,
    ) -> tuple[float, float] | None:
        """Point of the trail (extended to ``end``) one look-ahead from the reference point;
        ``beyond_trail`` (if given) when no trail point is that far."""
        pts = list(self._trail)
        if end is not None:
            pts.append(end)
        if not pts:
            return beyond_trail
        arr = np.asarray(pts, dtype=np.float64)
        d = np.hypot(arr[:, 0] - obs.x_m, arr[:, 1] - obs.y_m)
        look = self._lookahead(obs)
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        ahead = (arr[:, 0] - obs.x_m) * c + (arr[:, 1] - obs.y_m) * s > 0.0
        # never aim behind: a point left behind (the trail stopped growing) is skipped
        beyond = np.flatnonzero((d >= look) & ahead)
        if beyond.size == 0:
            if beyond_trail is not None:
                return beyond_trail
            return float(arr[-1, 0]), float(arr[-1, 1])
        j = int(beyond[0])
        if j == 0 or d[j - 1] >= look:
            return float(arr[j, 0]), float(arr[j, 1])
        # the point of segment (j-1, j) at distance `look` from the reference point
        a, b = arr[j - 1], arr[j]
        e = b - a
        w = a - np.array([obs.x_m, obs.y_m])
        qa, qb, qc = float(e @ e), 2.0 * float(w @ e), float(w @ w) - look * look
        disc = max(qb * qb - 4.0 * qa * qc, 0.0)
        t = (-qb + math.sqrt(disc)) / (2.0 * qa) if qa > 0 else 1.0
        t = min(max(t, 0.0), 1.0)
        return float(a[0] + t * e[0]), float(a[1] + t * e[1])

    def _pursuit(self, obs: Observation, speed: float, target: tuple[float, float] | None) -> float:
        """Pure-pursuit yaw rate at the speed the vehicle will reach this step."""
        if target is None:
            return 0.0
        lim = obs.limits
        next_speed = min(
            max(speed, obs.speed_mps - lim.max_decel_mps2 * obs.dt_s),
            obs.speed_mps + lim.max_accel_mps2 * obs.dt_s,
        )
        dx, dy = target[0] - obs.x_m, target[1] - obs.y_m
        dist = math.hypot(dx, dy)
        if dist < 1e-6:
            return 0.0
        alpha = math.atan2(dy, dx) - obs.yaw_rad
        return max(next_speed, 0.0) * 2.0 * math.sin(alpha) / dist

    # ------------------------------------------------------------------ lost

    def _stop(self, obs: Observation) -> Command:
        speed = max(obs.speed_mps - self.params.comfort_decel_mps2 * obs.dt_s, 0.0)
        self._prune_trail(obs)
        target = self._trail_target(obs, None) if len(self._trail) else None
        if target is not None:
            c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
            if (target[0] - obs.x_m) * c + (target[1] - obs.y_m) * s <= 0.0:
                target = None  # the trail is used up
        return Command(speed_mps=speed, yaw_rate_radps=self._pursuit(obs, speed, target))

    def _guarded(self, obs: Observation, cmd: Command) -> Command:
        """The fallback's command with its speed capped by the laser clearance on its arc."""
        p, lim = self.params, obs.limits
        # the arc the fallback steers: its yaw rate over the speed it will reach (dividing
        # by a speed near zero would bend the arc into the cars beside a standing vehicle)
        v_next = min(
            max(cmd.speed_mps, obs.speed_mps - lim.max_decel_mps2 * obs.dt_s),
            obs.speed_mps + lim.max_accel_mps2 * obs.dt_s,
        )
        curvature = cmd.yaw_rate_radps / v_next if v_next > 1e-3 else 0.0
        clearance = self._arc_clearance(obs, curvature)
        safe = _krauss_safe_speed(
            clearance - p.standstill_gap_m, 0.0, p.comfort_decel_mps2, p.reaction_time_s
        )
        return replace(cmd, speed_mps=min(cmd.speed_mps, safe))

    def _guard_margin_m(self, obs: Observation) -> float:
        """The band's margin beside the body: `guard_margin_junction_m` with any of the
        body in a junction (from the fallback's arc length), else `guard_margin_rel`
        widths."""
        p = self.params
        front_m = self._fallback._s_m + obs.front_offset_m
        if obs.path is not None and obs.path.junction_within(front_m - obs.length_m, front_m):
            return p.guard_margin_junction_m
        return p.guard_margin_rel * obs.width_m

    def _arc_clearance(self, obs: Observation, curvature: float) -> float:
        """Free distance from the front bumper along the arc of the given curvature."""
        pts = self._scan_points
        if pts.size == 0:
            return math.inf
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        dx = pts[:, 0] - (obs.x_m + obs.front_offset_m * c)
        dy = pts[:, 1] - (obs.y_m + obs.front_offset_m * s)
        x, y = c * dx + s * dy, -s * dx + c * dy
        half = 0.5 * obs.width_m + self._guard_margin_m(obs)
        if abs(curvature) < 1e-4:
            along, lateral = x, np.abs(y)
        else:
            radius = 1.0 / abs(curvature)
            y = y if curvature > 0 else -y  # mirror right turns into left turns
            along = radius * np.arctan2(x, radius - y)
            lateral = np.abs(np.hypot(x, y - radius) - radius)
        hit = (along > 0.0) & (lateral <= half)
        return float(along[hit].min()) if hit.any() else math.inf
