"""Laser-only follower: tracks the predecessor's rear in the scan and drives on its path.

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
   speed capped by the laser's clearance along the commanded arc, in a band a quarter
   width wider than the body on each side, 5 cm in a junction) until a predecessor
   is confirmed again, then follows again. Never inside a junction: a follower lost
   with its body in a junction, or whose comfortable stop would end in one, drives out
   on its route as ``route_following`` does (mode ``leaving_junction``), then stops.

Each command carries its ``Telemetry``: the mode, the measured gap (the straight-line
gap of 3., from the own front bumper to the tracked rear; None unless following) and the
spacing policy (``GapPolicy``). The arithmetic runs in compiled numba kernels
(``platoon_sumo.kernels``): a step costs tens of microseconds, not milliseconds
(``docs/performance.md``, "Controllers").

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
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, Literal

import numpy as np

from platoon_sumo.config_loader import bounded, require, require_choice, require_positive
from platoon_sumo.control.base import (
    CONTROLLERS,
    Command,
    GapPolicy,
    MemberFailure,
    Observation,
    ObservationColumns,
    ObservationRows,
    Telemetry,
)
from platoon_sumo.control.follower_rows import FollowerRows, PathTables
from platoon_sumo.control.perception import (
    PerceptionParams,
    RearCandidate,
    RearTracker,
    TrackerParams,
    candidate_from_row,
    params_array,
    ray_table,
)
from platoon_sumo.control.route_following import RouteFollowing, RouteFollowingParams
from platoon_sumo.frozen import frozen_from_dict
from platoon_sumo.kernels.follower import (
    CONST_NAMES,
    LAW_NAMES,
    arc_clearance_kernel,
    follow_kernel,
    krauss_safe_speed,
    perceive_kernel,
    pursuit,
    start_gate_kernel,
    trail_kernel,
)
from platoon_sumo.kernels.following import (
    FOLLOWED,
    LANE_UNREAD,
    LOST,
    PARAM_NAMES,
    RAISE,
    SKIPPED,
    STATE_NAMES,
    following_batch_kernel,
    following_step_kernel,
)
from platoon_sumo.kernels.perception import CANDIDATE_COLUMNS, STATE_SIZE
from platoon_sumo.path import FloatArray, RoutePath
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.vehicles import MotionLimits

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
    standstill_gap_m: float = bounded(2.5, ge=0, le=1000)
    """Bumper-to-rear gap at standstill, or always with constant_distance [m] (robots 0.35)."""
    time_gap_s: float = bounded(1.0, ge=0, le=100)
    """Time gap of the constant_time_gap policy [s] (robots 0.6)."""
    k_gap_1ps2: float = bounded(0.3, gt=0, le=100)
    """Acceleration per metre of gap error [1/s^2] (robots 0.3-1)."""
    k_rate_1ps: float = bounded(0.8, ge=0, le=100)
    """Acceleration per m/s of range rate [1/s] (robots 0.8-1.5)."""
    min_gap_m: float = bounded(1.0, ge=0, le=1000)
    """Hard floor: full stop when anything is this close ahead; safe speed keeps it [m]
    (robots 0.15)."""
    comfort_decel_mps2: float = bounded(2.5, gt=0, le=50)
    """Deceleration of the safe-speed term and of the stop when lost [m/s^2] (robots 0.5)."""
    reaction_time_s: float = bounded(0.5, ge=0, le=100)
    """Reaction time of the Krauss-style safe speed [s]."""
    lookahead_min_m: float = bounded(4.0, gt=0, le=1000)
    """Shortest pure-pursuit look-ahead [m] (robots 0.3)."""
    lookahead_time_s: float = bounded(0.5, ge=0, le=100)
    """Look-ahead = max(lookahead_min_m, lookahead_time_s * speed) [s]."""
    trail_spacing_m: float = bounded(0.5, gt=0, le=1000)
    """Distance between stored trail points [m] (robots 0.02)."""
    max_trail_points: int = bounded(4000, ge=2, le=100_000)
    """Oldest trail points are dropped beyond this many."""
    steer_at: Literal["trail", "predecessor"] = "trail"
    """Pure pursuit on the predecessor's trail, or straight at its current rear."""
    on_lost: Literal["stop", "route_following"] = "stop"
    """What to do without a predecessor: stop comfortably, or follow the own route."""
    leave_junctions: bool = True
    """Lost with the body in a junction, or where a comfortable stop would end in one,
    drive out on the own route before stopping (False: stop wherever lost)."""
    guard_margin_rel: float = bounded(0.25, ge=0, le=10)
    """Lost on the own route: the speed is capped by the laser's clearance along the
    commanded arc, in a band of the body plus this share of its width on each side."""
    guard_margin_junction_m: float = bounded(0.05, ge=0, le=10)
    """The band's margin on each side while the body is in a junction [m]; absolute, not
    scaled with the width (5 cm is a fifth of a paper robot's width). A car waiting
    inside a junction may stand a few decimetres beside the path (where the network's
    internal lanes come close); with the wide margin the follower stopped beside it in
    the junction, and the waiting car stood there too, to the end (the DRT district)."""
    predecessor_width_m: float | None = bounded(None, gt=0, le=20)
    """Expected rear width of the predecessor [m]; None: the follower's own width."""
    corridor_half_width_m: float | Literal["lane"] | None = "lane"
    """Half-width of the own route's corridor in which a predecessor is tracked and its
    trail followed [m]; "lane": half the lane width at the rear's point of the route plus
    ``corridor_margin_rel`` lane widths (scales with the network: cars and robots);
    None: no corridor (any vehicle in the start gate, followed anywhere)."""
    corridor_margin_rel: float = bounded(0.2, ge=0, le=10)
    """Margin of the "lane" corridor beyond half the lane width, in lane widths
    (3.2 m lanes: 2.24 m half-width; the paper world's 0.5 m lanes: 0.35 m)."""
    corridor_exit_s: float = bounded(0.5, ge=0, le=100)
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
            "guard_margin_rel",
            "guard_margin_junction_m",
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


_SCRATCH: dict[int, tuple[FloatArray, FloatArray]] = {}


def _scratch(rays: int) -> tuple[FloatArray, FloatArray]:
    """The hit-point and candidate-row buffers of ``perceive_kernel`` for scans of this
    many rays, shared by every follower: they hold one scan's work until the follower
    has read it (the candidate it keeps is copied out), and one pair instead of one per
    follower keeps the working set of a step in the CPU's caches (80 followers with
    1081-ray scans: 7.6 MB otherwise)."""
    found = _SCRATCH.get(rays)
    if found is None:
        found = _SCRATCH[rays] = (np.zeros((rays, 2)), np.zeros((rays, len(CANDIDATE_COLUMNS))))
    return found


class _ScanBuffers:
    """What ``perceive_kernel`` works in for one scan geometry: the rays' cosines and
    sines, its constants (``CONST_NAMES``), the shared scratch buffers (``_scratch``)
    and where the candidate associated last is kept."""

    def __init__(
        self, key: tuple[float, ...], scan: LaserScan, width: float, params: LaserFollowerParams
    ):
        self.key = key
        self.cos_a, self.sin_a = ray_table(scan)
        t = params.tracker
        self.consts = np.array(
            [
                scan.angle_increment, scan.range_min, width, params.min_gap_m,
                t.accel_noise_mps2, t.meas_noise_m, t.gate_chi2,
            ],
            dtype=np.float64,
        )  # fmt: skip
        n = scan.ranges.size
        self.pts, self.rows = _scratch(n)
        self.cand_pts = np.zeros((n, 2))
        self.cand_row = np.zeros(len(CANDIDATE_COLUMNS))
        self.cand_n = 0
        """The candidate associated last: its row and its cluster's first points."""

    def last_candidate(self) -> RearCandidate:
        """The candidate associated last, as a record (``RearTracker.last_candidate``)."""
        return candidate_from_row(self.cand_pts[: self.cand_n].copy(), self.cand_row.tolist())


class _RouteShadow(RouteFollowing):
    """The ``route_following`` fallback. Its state between steps (besides caches of the
    path) is its arc length on the route, which ``advance`` moves on exactly as its
    ``step`` does (same hint, same window), so it is asked for a command only on the
    steps that use one (the equivalence tests check this against a fallback stepped
    every step)."""

    def advance(self, obs: Observation) -> None:
        p = self.params
        lookahead = max(p.lookahead_min_m, p.lookahead_time_s * obs.speed_mps)
        window = max(20.0, 3 * lookahead)
        self._s_m = obs.path.project_sl(obs.x_m, obs.y_m, self._s_m, window)[0]


@CONTROLLERS.register("laser_follower")
class LaserFollower:
    """Follows the vehicle ahead with the laser only (see the module docstring).

    The arithmetic runs in compiled kernels (``platoon_sumo.kernels.follower``), one call
    per task: ``perceive_kernel`` on a new scan (segmentation, rear fits, blocked check,
    tracker update), ``follow_kernel`` while following (trail, spacing law, pure
    pursuit), ``RoutePath.project_lane`` for the route (each point once per step). This
    class keeps the state and the decisions between them.
    """

    Params: ClassVar[type[LaserFollowerParams]] = LaserFollowerParams
    reads_link_ahead: ClassVar[bool] = False

    def __init__(self, params: LaserFollowerParams | None = None):
        self.params = params or LaserFollowerParams()
        self.tracker = RearTracker(self.params.tracker)
        self._fallback = _RouteShadow(self.params.fallback)
        self._telemetry: dict[str, Telemetry] = {}
        self._perception_array = params_array(self.params.perception)
        # the trail lives in rows [lo, hi) of a buffer: compacted when it is full, or
        # doubled (up to twice the most points kept) when more than half of it is trail
        self._trail_buf: FloatArray = np.zeros((min(64, 2 * self.params.max_trail_points + 2), 2))
        self._arrays_of: RoutePath | None = None
        self._path_arrays: tuple[np.ndarray, ...] = ()
        self._rows: FollowerRows | None = None
        """The pool of ``step_many`` whose rows hold this follower's arrays, and its row."""
        self._slot = -1
        self._pooled_buffers: _ScanBuffers | None = None
        self._pooled_law: FloatArray | None = None
        self._joined = False
        """Whether the pooled state row holds this follower's numbers (``_join_rows``)."""
        self.reset()

    # ------------------------------------------------------------------ public API

    def reset(self) -> None:
        self._joined = False
        self.tracker.reset()
        self._fallback.reset()
        self._trail_lo = self._trail_hi = 0
        self._trail_last = (0.0, 0.0)
        self._last_scan: LaserScan | None = None
        self._mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._blocked = False
        self._in_view = False
        self._clearance_scan: LaserScan | None = None
        """The last processed scan, for the clearance along the fallback's arc."""
        self._scan_buffers: _ScanBuffers | None = None
        self._track: TrackedPredecessor | None = None
        self._track_args: tuple[float, float, float, bool, float, float, float] | None = None
        """The fields of ``track``, built when asked for."""
        self._route: RoutePath | None = None
        self._route_s: float | None = None
        self._ahead_memo: tuple[float, float, tuple[float, float, float] | None] | None = None
        self._corridor_memo: tuple[float, float, bool] | None = None
        """The last point projected on the route this step, and its corridor test."""
        self._outside_since: float | None = None
        self._measured_gap_m: float | None = None
        self._look = self.params.lookahead_min_m
        """The pure-pursuit look-ahead of the current step."""
        self._law_limits: MotionLimits | None = None
        self._law_array: FloatArray = np.zeros(0)
        self.mode = "lost"

    def desired_gap_m(self, speed_mps: float) -> float:
        """The spacing policy: desired bumper-to-rear gap at a given own speed [m]."""
        p = self.params
        if p.policy == "constant_distance":
            return p.standstill_gap_m
        return p.standstill_gap_m + p.time_gap_s * max(speed_mps, 0.0)

    @cached_property
    def gap_policy(self) -> GapPolicy:
        """The spacing policy as data (for the trajectory table)."""
        p = self.params
        time_gap = p.time_gap_s if p.policy == "constant_time_gap" else 0.0
        return GapPolicy(p.standstill_gap_m, time_gap)

    @property
    def track(self) -> TrackedPredecessor | None:
        """The confirmed predecessor track at the last step, or None."""
        if self._joined:
            self._leave_rows()
        if self._track is None and self._track_args is not None:
            self._track = TrackedPredecessor(*self._track_args)
        return self._track

    @property
    def trail(self) -> FloatArray:
        """The stored trail of the predecessor's rear positions (world frame), (n, 2)."""
        if self._joined:
            self._leave_rows()
        return self._trail_buf[self._trail_lo : self._trail_hi].copy()

    # ------------------------------------------------------------------ step

    def step(self, observation: Observation) -> Command:
        if self._joined:
            self._leave_rows()
        self._begin(observation.speed_mps)
        return self._finish(observation, *self._fused_step(observation))

    @staticmethod
    def step_many(
        controllers: Sequence[LaserFollower], observations: Sequence[Observation]
    ) -> list[Command]:
        """``step`` for many followers: the fused steps of all that have one (see
        ``_fused_step``) in one kernel call (``kernels.following.following_batch_kernel``)
        on pooled rows of their arrays (``control.follower_rows``), then each follower's
        step as ``step`` goes on from there, in order. Handed `ObservationRows` (the
        loop's columns), a follower whose batched step keeps following never has its
        `Observation` built. A subclass that overrides ``step`` is stepped with it."""
        if isinstance(observations, ObservationRows):
            cols, at = observations.columns, observations.rows
        else:
            cols, at = ObservationColumns.of(observations), range(len(observations))
        batches: dict[FollowerRows, list[int]] = {}
        speed, path, scan, limits, width = (
            cols.speed_mps,
            cols.path,
            cols.scan,
            cols.limits,
            cols.width_m,
        )
        for k, c in enumerate(controllers):
            if type(c).step is not LaserFollower.step:
                continue
            r = at[k]
            rows = c._batch_entry(speed[r], path[r], scan[r], limits[r], width[r])
            if rows is not None:
                batches.setdefault(rows, []).append(k)
        outs: list[list[float] | None] = [None] * len(controllers)
        for rows, members in batches.items():
            followers, rows_at = [controllers[k] for k in members], [at[k] for k in members]
            for k, values in zip(members, _step_batch(rows, followers, cols, rows_at), strict=True):
                outs[k] = values
        commands = []
        for k, (c, out) in enumerate(zip(controllers, outs, strict=True)):
            try:
                if type(c).step is not LaserFollower.step:
                    commands.append(c.step(observations[k]))
                    continue
                if out is not None and out[0] == FOLLOWED:  # booked in the rows
                    c._last_scan = c._clearance_scan = scan[at[k]]
                    c._in_view, c._blocked, c._measured_gap_m = bool(out[16]), bool(out[5]), out[24]
                    c._track = None
                    c.mode = "following"
                    commands.append(c._command(out[22], out[23], None, int(out[31]), bool(out[32])))
                    continue
                obs = observations[k]
                if out is None:  # not in a batch
                    done = c._fused_step(obs)
                else:  # booked as after a single call, from the rows as they were
                    c._leave_rows()
                    if out[0] == SKIPPED:
                        done = c._fused_step(obs)
                    else:
                        assert c._pooled_buffers is not None  # _pooled_rows
                        done = c._fused_apply(obs, c._pooled_buffers, out)
                commands.append(c._finish(obs, *done))
            except Exception as exc:
                raise MemberFailure(k, exc) from exc
        return commands

    def _batch_entry(
        self,
        speed_mps: float,
        path: RoutePath,
        scan: LaserScan | None,
        limits: MotionLimits,
        width_m: float,
    ) -> FollowerRows | None:
        """``_begin``; then the pool whose batched kernel takes this step (the follower's
        numbers in its rows), or None (the numbers back in the attributes)."""
        self._begin(speed_mps)
        joined = self._joined
        rows = None
        if self._fusable(scan, path, joined):
            assert scan is not None  # _fusable
            rows = self._pooled_rows(scan, path, limits, width_m)
        if rows is None:
            if joined:
                self._leave_rows()
        elif not joined:
            self._join_rows()
        return rows

    def _begin(self, speed_mps: float) -> None:
        p = self.params
        self._ahead_memo = self._corridor_memo = None  # reused within one step only
        self._look = max(p.lookahead_min_m, p.lookahead_time_s * speed_mps)

    def _finish(
        self, obs: Observation, perceived: bool, followed: tuple[float, float, int, bool] | None
    ) -> Command:
        """The step after the fused kernel (or without it): the perception where the
        kernel did not run, then following, the lost modes and the command."""
        p = self.params
        if not perceived:
            if p.corridor_half_width_m is not None:
                self._locate_on_route(obs)
            if obs.scan is not None and obs.scan is not self._last_scan:
                self._perceive(obs, obs.scan)
        lane_change, keep_lane = 0, False
        heading: float | None = None
        if followed is not None:
            self.mode = "following"
            speed, yaw_rate, lane_change, keep_lane = followed
        elif self.tracker.confirmed:
            self._fallback.advance(obs)  # so it knows where on the route it is
            self.mode = "following"
            speed, yaw_rate, lane_change, keep_lane = self._follow(obs)
        else:
            self._track = self._track_args = None
            if p.on_lost == "route_following" or (p.leave_junctions and self._in_junction(obs)):
                self.mode = p.on_lost if p.on_lost == "route_following" else "leaving_junction"
                shadow = self._fallback._step(obs, math.inf)  # blind to SUMO's leader
                speed = self._guarded(obs, shadow)
                yaw_rate, lane_change, heading = (
                    shadow.yaw_rate_radps,
                    shadow.lane_change,
                    shadow.heading_rad,
                )
            else:
                self.mode = "stopping"
                speed, yaw_rate = self._stop(obs)
        return self._command(speed, yaw_rate, heading, lane_change, keep_lane)

    def _command(
        self, speed: float, yaw_rate: float, heading: float | None, lane_change: int,
        keep_lane: bool,
    ) -> Command:  # fmt: skip
        """The step's command in the current mode (none but a stop while blocked)."""
        if self._blocked:
            speed, lane_change, heading, keep_lane = 0.0, 0, None, False
        if self.mode == "following":
            telemetry = frozen_from_dict(Telemetry, {
                "mode": self.mode,
                "measured_gap_m": self._measured_gap_m,
                "gap_policy": self.gap_policy,
                "desired_accel_mps2": None,
            })  # fmt: skip
        else:  # the same for every step in this mode (frozen): made once
            telemetry = self._telemetry.get(self.mode) or self._telemetry.setdefault(
                self.mode, Telemetry(self.mode, None, self.gap_policy)
            )
        return frozen_from_dict(Command, {
            "speed_mps": speed,
            "yaw_rate_radps": yaw_rate,
            "heading_rad": heading,
            "lane_change": lane_change,
            "telemetry": telemetry,
            "keep_lane": keep_lane,
        })  # fmt: skip

    # ------------------------------------------------------------------ fused step

    def _fused_step(self, obs: Observation) -> tuple[bool, tuple[float, float, int, bool] | None]:
        """The step's locate, perceive and, while the track stays confirmed, follow in one
        kernel call (``kernels.following``) where it applies: a corridor, a new scan, an
        active track on this route, room in the trail buffer. Returns (whether the scan
        was processed, the following command's speed, yaw rate, lane request and keep the
        lane, or None: the track is lost, or the kernel did not run)."""
        if not self._fusable(obs.scan, obs.path):
            return False, None
        p, scan, tracker = self.params, obs.scan, self.tracker
        assert scan is not None  # _fusable
        b = self._buffers(scan, p.predecessor_width_m or obs.width_m)
        if obs.path is not self._arrays_of:
            self._arrays_of, self._path_arrays = obs.path, obs.path.follower_kernel_arrays
        xy, blocks, widths, codes, spans, shift, geometry = self._path_arrays
        out = following_step_kernel(
            xy, blocks, widths, codes, spans, shift, geometry, scan.ranges, b.cos_a, b.sin_a,
            b.consts, self._perception_array, tracker.state_array, b.pts, b.rows, b.cand_pts,
            b.cand_row, self._trail_buf, self._law(obs.limits), self._fused_params,
            *self._fused_scalars(obs, scan),
        )  # fmt: skip
        return self._fused_apply(obs, b, out)

    def _fusable(self, scan: LaserScan | None, path: RoutePath, joined: bool = False) -> bool:
        """Whether the fused kernel applies this step: a corridor, a new scan, an active
        track on this route, room in the trail buffer (`joined`: the pooled rows hold the
        track and the trail, and the batched kernel checks the room)."""
        return not (
            self.params.corridor_half_width_m is None
            or scan is None
            or scan is self._last_scan
            or path is not self._route
            or (
                not joined
                and (
                    not self.tracker.active
                    or self._route_s is None
                    or self._trail_hi >= len(self._trail_buf)
                )
            )
        )

    def _fused_scalars(self, obs: Observation, scan: LaserScan) -> list[Any]:
        """``following_step_kernel``'s arguments after its arrays (time .. since)."""
        tracker, since = self.tracker, self._outside_since
        return [
            float(obs.time_s), obs.dt_s, obs.x_m, obs.y_m, obs.yaw_rad, obs.speed_mps,
            obs.front_offset_m, obs.length_m, obs.lane_offset_m, self._look,
            self._route_s,
            self._fallback._s_m, float(scan.origin_x_m), float(scan.origin_y_m),
            float(scan.heading_rad), tracker.hits, tracker.missed, tracker.last_hit_s,
            self._trail_lo, self._trail_hi, *self._trail_last, since is not None,
            0.0 if since is None else since,
        ]  # fmt: skip

    def _fused_apply(
        self, obs: Observation, b: _ScanBuffers, out: Sequence[float]
    ) -> tuple[bool, tuple[float, float, int, bool] | None]:
        """Keep what ``following_step_kernel`` returned (``out``: its values in order,
        as it gives them or as numbers from ``following_batch_kernel``)."""
        (
            status, route_s, mount_x, mount_y, mount_yaw, blocked, k, cand_n, tx, ty, tvx,
            tvy, var_p, var_v, dropped, has_since, in_view, lo, hi, last_x, last_y,
            fallback_s, speed, yaw_rate, gap, range_rate, lead_speed, range_m, bearing, rx, ry,
            lane, keep, *raise_args,
        ) = out  # fmt: skip
        status = int(status)
        if status == RAISE:
            obs.path.project_lane(*raise_args)  # raises (a hint or window not finite)
        tracker, since = self.tracker, self._outside_since
        b.cand_n = int(cand_n)
        self._route_s = route_s
        self._last_scan = self._clearance_scan = obs.scan
        self._mount = (mount_x, mount_y, mount_yaw)
        tracker.record_step(obs.time_s, int(k), (tx, ty, tvx, tvy), var_p, var_v, b.last_candidate)
        if dropped:
            tracker.reset()
        self._outside_since = (since if since is not None else obs.time_s) if has_since else None
        self._in_view = in_view = bool(in_view)
        self._blocked = bool(blocked)
        self._trail_lo, self._trail_hi, self._trail_last = int(lo), int(hi), (last_x, last_y)
        if status == LOST:
            return True, None
        self._fallback._s_m = fallback_s
        self._measured_gap_m = gap
        self._track = None
        self._track_args = (range_m, bearing, range_rate, in_view, lead_speed, rx, ry)
        if status == LANE_UNREAD:
            return True, (speed, yaw_rate, *self._lane_request(obs, rx, ry))
        return True, (speed, yaw_rate, int(lane), bool(keep))

    # ------------------------------------------------------------------ pooled rows

    def _pooled_rows(
        self, scan: LaserScan, path: RoutePath, limits: MotionLimits, width_m: float
    ) -> FollowerRows | None:
        """The pool this follower's fused step can run in, its arrays on their rows there
        (joining it first), or None (a scan of another size than the pool's)."""
        b = self._buffers(scan, self.params.predecessor_width_m or width_m)
        rows = self._rows
        if rows is None:
            rows = _pool(scan.ranges.size, self.params)
            rows.join(self)
        a, slot = rows.arrays, self._slot
        if b is not self._pooled_buffers:
            if b.cos_a.shape != a["cos_a"].shape[1:]:
                return None
            for name in _BUFFER_ROWS:
                a[name][slot] = getattr(b, name)
                setattr(b, name, a[name][slot])
            self._pooled_buffers = b
        law = self._law_array if limits is self._law_limits else self._law(limits)
        if law is not self._pooled_law:
            a["law"][slot] = law
            self._law_array = self._pooled_law = a["law"][slot]
        if path is not self._arrays_of:
            self._arrays_of, self._path_arrays = path, path.follower_kernel_arrays
        return rows

    def _join_rows(self) -> None:
        """Hand the numbers kept between steps to the pooled state row (``STATE_NAMES``):
        the batched kernel books its following steps there, and the attributes below are
        stale until ``_leave_rows``."""
        assert self._rows is not None and self._pooled_buffers is not None
        t, since, track = self.tracker, self._outside_since, self._track_args
        self._rows.arrays["state_rows"][self._slot] = [
            self._route_s, self._fallback._s_m, t.hits, t.missed, t.last_hit_s,
            self._trail_lo, self._trail_hi, *self._trail_last, since is not None,
            0.0 if since is None else since, 0.0, t.time_s, *t._x, t._position_variance,
            t._velocity_variance, *self._mount, self._pooled_buffers.cand_n,
            track is not None, *(track if track is not None else (0.0,) * 7),
        ]  # fmt: skip
        self._joined = True

    def _leave_rows(self) -> None:
        """The numbers the pooled state row holds back into the attributes."""
        assert self._rows is not None and self._pooled_buffers is not None
        (
            route_s, fallback_s, hits, missed, last_hit_s, lo, hi, last_x, last_y, has_since,
            since, hit, track_time, tx, ty, tvx, tvy, var_p, var_v, mount_x, mount_y,
            mount_yaw, cand_n, has_track, *track,
        ) = self._rows.arrays["state_rows"][self._slot].tolist()  # fmt: skip
        t, b = self.tracker, self._pooled_buffers
        self._route_s, self._fallback._s_m = route_s, fallback_s
        t.hits, t.missed, t.last_hit_s = int(hits), int(missed), last_hit_s
        t.time_s, t._x = track_time, (tx, ty, tvx, tvy)
        t._position_variance, t._velocity_variance = var_p, var_v
        if hit:
            t._last = b.last_candidate
        self._trail_lo, self._trail_hi, self._trail_last = int(lo), int(hi), (last_x, last_y)
        self._outside_since = since if has_since else None
        self._mount = (mount_x, mount_y, mount_yaw)
        b.cand_n = int(cand_n)
        if has_track:
            range_m, bearing, rate, in_view, speed, rx, ry = track
            self._track_args = (range_m, bearing, rate, bool(in_view), speed, rx, ry)
        self._joined = False

    def bind(self, pool: FollowerRows, slot: int) -> None:
        """Work on rows `slot` of the pool's arrays from now on (``FollowerRows.join``,
        and again after it grows): the values are copied there first."""
        a = pool.arrays
        self._rows, self._slot = pool, slot
        self.tracker.keep_state_in(a["state"][slot])
        a["trail"][slot, : len(self._trail_buf)] = self._trail_buf
        self._trail_buf = a["trail"][slot]
        a["perception"][slot] = self._perception_array
        self._perception_array = a["perception"][slot]
        a["params"][slot] = self._fused_params
        self.__dict__["_fused_params"] = a["params"][slot]
        b = self._pooled_buffers
        if b is not None:
            for name in _BUFFER_ROWS:
                a[name][slot] = getattr(b, name)
                setattr(b, name, a[name][slot])
        if self._pooled_law is not None:
            a["law"][slot] = self._pooled_law
            self._law_array = self._pooled_law = a["law"][slot]

    @cached_property
    def _fused_params(self) -> FloatArray:
        """``following_step_kernel``'s parameters (``PARAM_NAMES``)."""
        p, t = self.params, self.params.tracker
        lane = p.corridor_half_width_m == "lane"
        return np.array(
            [
                1.0 if lane else 0.0,
                p.corridor_margin_rel if lane else float(p.corridor_half_width_m or 0.0),
                p.corridor_exit_s, t.confirm_scans, t.max_missed_scans, t.lost_after_s,
                p.trail_spacing_m, p.max_trail_points, 1.0 if p.steer_at == "trail" else 0.0,
                p.fallback.lookahead_min_m, p.fallback.lookahead_time_s,
            ],
            dtype=np.float64,
        )  # fmt: skip

    # ------------------------------------------------------------------ perception

    def _perceive(self, obs: Observation, scan: LaserScan) -> None:
        p = self.params
        self._last_scan = scan
        ox, oy, heading = scan.origin_x_m, scan.origin_y_m, scan.heading_rad
        hc, hs = math.cos(heading), math.sin(heading)  # the sensor pose at the scan
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        dx, dy = ox - obs.x_m, oy - obs.y_m
        self._mount = (c * dx + s * dy, -s * dx + c * dy, heading - obs.yaw_rad)
        width = self.params.predecessor_width_m or obs.width_m
        tracker = self.tracker
        was_active = tracker.active
        b = self._buffers(scan, width)
        n_pts, n_rows, blocked, k, b.cand_n, x, y, vx, vy, var_p, var_v = perceive_kernel(
            scan.ranges, b.cos_a, b.sin_a, b.consts, self._perception_array, was_active,
            tracker.state_array, float(obs.time_s), float(ox), float(oy), float(heading),
            b.pts, b.rows, b.cand_pts, b.cand_row,
        )  # fmt: skip
        if was_active:
            k = tracker.record_step(obs.time_s, k, (x, y, vx, vy), var_p, var_v, b.last_candidate)
        else:  # start only on a rear on the own route
            gate = p.tracker
            rows = b.rows[:n_rows]
            # the start gate first (as the tracker has it): fewer projections
            gated = start_gate_kernel(rows, gate.start_range_max_m, gate.start_lateral_m)
            keep = [
                j
                for j, r in zip(gated.tolist(), rows[gated].tolist(), strict=True)
                if self._in_corridor(obs, ox + hc * r[0] - hs * r[1], oy + hs * r[0] + hc * r[1])
            ] if gated.size else []  # fmt: skip
            k = -1  # no rear to start on (most scans of a lost follower): nothing changes
            if keep:
                own_v = (obs.speed_mps * c, obs.speed_mps * s)
                pose = (ox, oy, heading)
                points = b.pts[:n_pts].copy()  # the buffer is the next scan's
                k = tracker.step_rows(obs.time_s, points, rows[keep], pose, own_v, 0.5 * width)
        hit = k >= 0
        inside = tracker.active and self._in_corridor(obs, *tracker.position)
        if not tracker.active or inside:
            self._outside_since = None
        elif self._outside_since is None:
            self._outside_since = obs.time_s
        elif obs.time_s - self._outside_since > p.corridor_exit_s:
            tracker.reset()  # it turned off the route: lost, do not follow it
            self._outside_since = None
            hit = False
        self._in_view = hit
        if hit and not was_active:
            self._trail_lo = self._trail_hi = 0  # a new track: the old trail may be another's
        if hit and inside:
            self._append_trail(*tracker.position)
        self._blocked = blocked
        self._clearance_scan = scan

    def _buffers(self, scan: LaserScan, width: float) -> _ScanBuffers:
        """The kernel buffers and constants for this scan geometry and expected width."""
        key = (scan.angle_min, scan.angle_increment, scan.ranges.size, scan.range_min, width)
        b = self._scan_buffers
        if b is None or b.key != key:
            b = self._scan_buffers = _ScanBuffers(key, scan, width, self.params)
        return b

    # ------------------------------------------------------------------ route corridor

    def _locate_on_route(self, obs: Observation) -> None:
        """Track the follower's own arc length on its route (searched near the last one)."""
        if obs.path is not self._route:
            self._route, self._route_s = obs.path, None
        window = max(4.0 * obs.length_m, 2.0 * self._look)
        self._route_s = obs.path.project_sl(obs.x_m, obs.y_m, self._route_s, window)[0]

    def _ahead_on_route(
        self, obs: Observation, x_m: float, y_m: float
    ) -> tuple[float, float, float] | None:
        """A world point projected on the own route (arc length, lateral offset, lane
        width there), or None when it is not ahead."""
        if self._route_s is None:
            return None
        memo = self._ahead_memo
        if memo is not None and memo[0] == x_m and memo[1] == y_m:
            return memo[2]
        s0 = self._route_s
        # search from the own arc length to a few vehicle lengths beyond the point's range
        reach = 0.5 * (
            math.hypot(x_m - obs.x_m, y_m - obs.y_m) + _CORRIDOR_AHEAD_LENGTHS * obs.length_m
        )
        at: tuple[float, float, float] | None = obs.path.project_lane(x_m, y_m, s0 + reach, reach)
        if at is not None and at[0] <= s0:
            at = None
        self._ahead_memo = (x_m, y_m, at)
        return at

    def _in_corridor(self, obs: Observation, x_m: float, y_m: float) -> bool:
        """Does the world point lie ahead on the own route, within the corridor (centred on
        the own lane)?"""
        half_width = self.params.corridor_half_width_m
        if half_width is None or self._route_s is None:
            return True
        memo = self._corridor_memo
        if memo is not None and memo[0] == x_m and memo[1] == y_m:
            return memo[2]
        at = self._ahead_on_route(obs, x_m, y_m)
        if at is None:
            inside = False
        else:
            if half_width == "lane":
                half_width = (0.5 + self.params.corridor_margin_rel) * at[2]
            inside = abs(at[1] - obs.lane_offset_m) <= half_width
        self._corridor_memo = (x_m, y_m, inside)
        return inside

    def _lane_request(self, obs: Observation, x_m: float, y_m: float) -> tuple[int, bool]:
        """Where SUMO steers (lane actuation): +1 / -1 towards the lane of the same road in
        which the laser sees the predecessor, else 0 (also where either is in a junction
        or the route's own lane change: lanes are compared by the map, not by offsets);
        and whether to keep the lane, seeing the predecessor in it (so that SUMO's
        strategy does not take the follower out of its platoon's lane)."""
        at = self._ahead_on_route(obs, x_m, y_m) if self._in_view else None
        if at is None or self._route_s is None:
            return 0, False
        path, s, offset = obs.path, self._route_s, obs.lane_offset_m
        step = path.lane_step(s, offset, at[0], at[1])
        return step, step == 0 and path.same_lane(s, offset, at[0], at[1])

    def _route_target(self, obs: Observation) -> tuple[float, float] | None:
        """The own route's point one look-ahead beyond the follower (None without a corridor)."""
        if self._route_s is None:
            return None
        return obs.path.point_at(self._route_s + self._look)

    def _append_trail(self, x: float, y: float) -> None:
        lo, hi = self._trail_lo, self._trail_hi
        last_x, last_y = self._trail_last
        if hi == lo or math.hypot(x - last_x, y - last_y) >= self.params.trail_spacing_m:
            buf = self._trail_buf
            if hi == len(buf):  # full: move the trail to the front, in a larger buffer?
                size = len(buf)
                if hi - lo > size // 2:
                    size = min(2 * size, 2 * self.params.max_trail_points + 2)
                if size > len(buf):
                    buf = self._trail_buf = np.concatenate([buf, np.zeros((size - len(buf), 2))])
                buf[: hi - lo] = buf[lo:hi]
                lo, hi = 0, hi - lo
            buf[hi, 0] = x
            buf[hi, 1] = y
            hi += 1
            if hi - lo > self.params.max_trail_points:
                lo += 1
            self._trail_lo, self._trail_hi = lo, hi
            self._trail_last = (x, y)

    # ------------------------------------------------------------------ following

    def _follow(self, obs: Observation) -> tuple[float, float, int, bool]:
        """(speed, yaw rate, lane request, keep the lane) behind the tracked predecessor:
        the spacing law and pure pursuit on the trail (``follow_kernel``), towards the
        lane it is seen in."""
        p = self.params
        rx, ry, vx, vy = self.tracker.predicted_state(obs.time_s)
        # steering: never after a rear outside the route corridor (turning off the route)
        inside = self._in_corridor(obs, rx, ry)
        route = None if inside else self._route_target(obs)
        route_x, route_y = route if route is not None else (0.0, 0.0)
        mx, my, myaw = self._mount
        lo, speed, yaw_rate, gap, range_rate, lead_speed, range_m, bearing = follow_kernel(
            self._trail_buf, self._trail_lo, self._trail_hi, self._law(obs.limits),
            p.steer_at == "trail", obs.x_m, obs.y_m, obs.yaw_rad, obs.speed_mps,
            obs.front_offset_m, obs.dt_s, self._look, rx, ry, vx, vy, inside,
            route is not None, route_x, route_y, mx, my, myaw,
        )  # fmt: skip
        self._trail_lo = lo
        self._measured_gap_m = gap
        self._track = None
        self._track_args = (range_m, bearing, range_rate, self._in_view, lead_speed, rx, ry)
        return speed, yaw_rate, *self._lane_request(obs, rx, ry)

    def _law(self, limits: MotionLimits) -> FloatArray:
        """The parameters of ``follow_kernel`` (``LAW_NAMES``) with these limits."""
        if limits is not self._law_limits:
            p = self.params
            time_gap = p.time_gap_s if p.policy == "constant_time_gap" else 0.0
            self._law_array = np.array(
                [
                    p.k_gap_1ps2, p.k_rate_1ps, p.standstill_gap_m, time_gap, p.min_gap_m,
                    p.comfort_decel_mps2, p.reaction_time_s, limits.max_decel_mps2,
                    limits.max_accel_mps2, limits.max_speed_mps,
                ],
                dtype=np.float64,
            )  # fmt: skip
            self._law_limits = limits
        return self._law_array

    # ------------------------------------------------------------------ lost

    def _in_junction(self, obs: Observation) -> bool:
        """Is the body in a junction, or would a comfortable stop end in one? A lost
        follower then drives out on its route before it stops (a car standing inside a
        junction blocks the crossing traffic, which may not expect it there)."""
        self._fallback.advance(obs)
        stop_m = obs.speed_mps**2 / (2.0 * self.params.comfort_decel_mps2)
        return self._junction_from_body(obs, stop_m)

    def _junction_from_body(self, obs: Observation, ahead_m: float) -> bool:
        """Does the route run inside a junction from the rear bumper to `ahead_m` beyond
        the front one (the fallback's arc length locates the car on its route)?"""
        front_m = self._fallback._s_m + obs.front_offset_m
        return obs.path.junction_within(front_m - obs.length_m, front_m + ahead_m)

    def _guard_margin_m(self, obs: Observation) -> float:
        """The clearance band's margin beside the body (``guard_margin_rel``, or
        ``guard_margin_junction_m`` with any of the body in a junction)."""
        if obs.path is not None and self._junction_from_body(obs, 0.0):
            return self.params.guard_margin_junction_m
        return self.params.guard_margin_rel * obs.width_m

    def _stop(self, obs: Observation) -> tuple[float, float]:
        """(speed, yaw rate): brake comfortably along what is left of the trail."""
        speed = max(obs.speed_mps - self.params.comfort_decel_mps2 * obs.dt_s, 0.0)
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        # prune the trail behind, and its point one look-ahead away (or its last)
        lo, _, found, tx, ty = trail_kernel(
            self._trail_buf, self._trail_lo, self._trail_hi, obs.x_m, obs.y_m, c, s, False,
            0.0, 0.0, True, False, 0.0, 0.0, self._look,
        )  # fmt: skip
        self._trail_lo = lo
        if found < 0 or (tx - obs.x_m) * c + (ty - obs.y_m) * s <= 0.0:
            return speed, 0.0  # no trail, or it is used up
        lim = obs.limits
        return speed, pursuit(
            speed, obs.speed_mps, lim.max_decel_mps2, lim.max_accel_mps2, obs.dt_s, obs.x_m,
            obs.y_m, obs.yaw_rad, tx, ty,
        )  # fmt: skip

    def _guarded(self, obs: Observation, cmd: Command) -> float:
        """The fallback's speed capped by the laser clearance on its arc."""
        p, lim = self.params, obs.limits
        # the arc the fallback steers: its yaw rate over the speed it will reach (dividing
        # by a speed near zero would bend the arc into the cars beside a standing vehicle)
        v_next = min(
            max(cmd.speed_mps, obs.speed_mps - lim.max_decel_mps2 * obs.dt_s),
            obs.speed_mps + lim.max_accel_mps2 * obs.dt_s,
        )
        curvature = cmd.yaw_rate_radps / v_next if v_next > 1e-3 else 0.0
        clearance = self._arc_clearance(obs, curvature)
        safe = krauss_safe_speed(
            clearance - p.standstill_gap_m, 0.0, p.comfort_decel_mps2, p.reaction_time_s
        )
        return min(cmd.speed_mps, safe)

    def _arc_clearance(self, obs: Observation, curvature: float) -> float:
        """Free distance from the front bumper along the arc of the given curvature, to the
        hit points of the last processed scan (where they were when it was taken)."""
        scan = self._clearance_scan
        if scan is None:
            return math.inf
        c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
        return float(
            arc_clearance_kernel(
                np.ascontiguousarray(scan.ranges, dtype=np.float64),
                float(scan.angle_min),
                float(scan.angle_increment),
                float(scan.origin_x_m),
                float(scan.origin_y_m),
                float(scan.heading_rad),
                obs.x_m + obs.front_offset_m * c,
                obs.y_m + obs.front_offset_m * s,
                c,
                s,
                0.5 * obs.width_m + self._guard_margin_m(obs),
                float(curvature),
            )
        )


_BUFFER_ROWS = ("cos_a", "sin_a", "consts", "cand_pts", "cand_row")
"""The arrays of a follower's ``_ScanBuffers`` kept on its pooled rows."""

_PATH_TABLES = ("xy", "blocks", "widths", "codes", "spans", "shift", "geometry")

_POOLS: dict[tuple[int, int, int], FollowerRows] = {}
_PATHS: dict[FollowerRows, PathTables] = {}


def _pool(rays: int, params: LaserFollowerParams) -> FollowerRows:
    """The pool of the followers with scans of `rays` rays and `params`' trail size."""
    trail_rows = 2 * params.max_trail_points + 2
    perception = len(params_array(params.perception))
    key = (rays, trail_rows, perception)
    found = _POOLS.get(key)
    if found is None:
        found = _POOLS[key] = FollowerRows({
            "state": (STATE_SIZE,), "trail": (trail_rows, 2), "perception": (perception,),
            "params": (len(PARAM_NAMES),), "law": (len(LAW_NAMES),), "cos_a": (rays,),
            "sin_a": (rays,), "consts": (len(CONST_NAMES),), "cand_pts": (rays, 2),
            "cand_row": (len(CANDIDATE_COLUMNS),), "state_rows": (len(STATE_NAMES),),
        })  # fmt: skip
        _PATHS[found] = PathTables(_PATH_TABLES)
    return found


def _path_rows(path: object) -> tuple[np.ndarray, ...]:
    assert isinstance(path, RoutePath)
    xy, blocks, widths, codes, spans, shift, geometry = path.follower_kernel_arrays
    return xy, blocks, widths, codes, spans, shift, geometry[None, :]


def _step_batch(
    rows: FollowerRows, followers: list[LaserFollower], cols: ObservationColumns, at: list[int]
) -> list[list[float]]:
    """The fused steps of `followers` (all joined to `rows`; their observations rows `at`
    of `cols`) in one kernel call: each one's row of values, for ``step_many``."""
    paths = _PATHS[rows]
    path_of = paths.numbers([cols.path[r] for r in at], _path_rows)
    scans = [cols.scan[r] for r in at]
    # np.array copies a list of equal rows in about 40 % of np.stack's time
    ranges = np.array([scan.ranges for scan in scans if scan is not None], dtype=np.float64)
    r = np.array(at, dtype=np.int64)
    n = len(at)
    sensor = np.array(
        [(s.origin_x_m, s.origin_y_m, s.heading_rad) for s in scans if s is not None],
        dtype=np.float64,
    ).reshape(n, 3)
    inputs = np.column_stack([
        cols.time_s[r], cols.dt_s[r], cols.x_m[r], cols.y_m[r],
        cols.yaw_rad[r], cols.speed_mps[r], cols.front_offset_m[r], cols.length_m[r],
        cols.lane_offset_m[r], np.array([c._look for c in followers], dtype=np.float64),
        sensor,
    ])  # fmt: skip
    a = rows.arrays
    scratch_pts, scratch_rows = _scratch(rows.shapes["cos_a"][0])
    table, starts = paths.table, paths.starts
    out = following_batch_kernel(
        table("xy"), starts("xy"), table("blocks"), starts("blocks"), table("widths"),
        starts("widths"), table("codes"), starts("codes"), table("spans"), starts("spans"),
        table("shift"), starts("shift"), table("geometry"), np.array(path_of, dtype=np.int64),
        ranges, a["cos_a"], a["sin_a"], a["consts"], a["perception"], a["state"], scratch_pts,
        scratch_rows, a["cand_pts"], a["cand_row"], a["trail"], a["law"], a["params"],
        a["state_rows"], np.array([c._slot for c in followers], dtype=np.int64), inputs,
    )  # fmt: skip
    values: list[list[float]] = out.tolist()
    return values
