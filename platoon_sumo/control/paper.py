"""The paper's laser-only platoon: Algorithm 1 (leader) and Algorithm 2 (follower).

Both are faithful readings of the pseudo-code in the paper (``shared/paper``, Section IV
and V). Every place where the pseudo-code is ambiguous is a documented choice, and every
departure needed in our world is a parameter with the paper's value as its default, so
a scenario can show what it changed. ``docs/paper.md`` explains each reading.

Conventions: scans follow ROS ``sensor_msgs/LaserScan`` and REP 117 (index 0 is
``angle_min``, the rightmost ray; ``+inf`` no return within ``range_max``; ``-inf`` a
return closer than ``range_min``; ``NaN`` a dropout). Yaw rates follow ROS: positive is
counter-clockwise (a left turn).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.config_loader import bounded, require, require_positive
from platoon_sumo.control.base import CONTROLLERS, Command, Observation
from platoon_sumo.sensors.laser import LaserScan

FloatArray = NDArray[np.float64]

# ----------------------------------------------------------------------------- leader


class Regions(NamedTuple):
    """Nearest valid range [m] in each of the leader's five scan regions (+inf: none)."""

    right: float
    fright: float
    front: float
    fleft: float
    left: float


def region_bounds(samples: int, count: int = 5) -> list[tuple[int, int]]:
    """Half-open index ranges ``[start, stop)`` of ``count`` equal regions, right to left.

    Region k holds indices ``k*n//count .. (k+1)*n//count - 1``: for 720 samples the
    paper's ``[0:143], [144:287], [288:431], [432:575], [576:719]``; for a count not
    divisible by 5 the regions differ by at most one sample.
    """
    cuts = [(k * samples) // count for k in range(count + 1)]
    return [(cuts[k], cuts[k + 1]) for k in range(count)]


def region_minima(ranges: FloatArray, range_min_m: float) -> Regions:
    """The paper's region distances: minimum VALID range in each of five equal regions.

    Finite readings count as measured; ``-inf`` (closer than ``range_min``) counts as
    ``range_min_m``, the most the sensor can say; ``+inf`` (no return) and ``NaN``
    (dropout) are ignored; a region with no valid reading is ``+inf`` (nothing seen).
    """
    r = np.asarray(ranges, dtype=np.float64)
    r = np.where(r == -np.inf, range_min_m, r)
    r = np.where(np.isfinite(r), r, np.inf)
    mins = [float(r[a:b].min(initial=np.inf)) for a, b in region_bounds(r.size)]
    return Regions(*mins)


@dataclass(frozen=True)
class PaperLeaderParams:
    """Algorithm 1's thresholds and velocities; thresholds are multiplied by ``scale``."""

    near_m: float = bounded(1.0, gt=0, le=1000)
    """The paper's ``1`` (Front, Fleft and Fright in rules 1, 3, 4, 5, 6)."""
    front_far_m: float = bounded(2.0, gt=0, le=1000)
    """The paper's ``Front < 2`` (rule 2)."""
    fleft_far_m: float = bounded(3.0, gt=0, le=1000)
    """The paper's ``Fleft < 3`` (rule 2)."""
    fright_clear_m: float = bounded(0.5, gt=0, le=1000)
    """The paper's ``Fright > 0.5`` / ``Fright < 0.5`` (rules 1, 2, 6)."""
    fright_wide_m: float = bounded(0.7, gt=0, le=1000)
    """The paper's ``Fright > 0.7`` (rule 5; unreachable in the paper's order, see docs)."""
    scale: float = bounded(1.0, gt=0, le=1000)
    """Multiplies every threshold above, to fit the rules to a world's lane width."""
    linear_mps: float = bounded(0.1, ge=0, le=150)
    """The paper's ``linearVel = 0.1`` [m/s]."""
    angular_radps: float = bounded(0.1, ge=0, le=50)
    """Magnitude of the paper's ``angularVel = +-0.1`` [rad/s]."""
    turn_sign: float = -1.0
    """ROS yaw rate = ``turn_sign`` x the paper's angularVel. ``-1`` (default): the
    paper's negative angularVel is a LEFT turn, as its text says ("turns left when near
    to obstacle or wall"); ``+1``: the literal ROS sign (negative = clockwise)."""

    def __post_init__(self) -> None:
        require_positive(
            self, "near_m", "front_far_m", "fleft_far_m", "fright_clear_m", "fright_wide_m"
        )
        require(self.scale > 0, "scale", "must be > 0")
        require(self.linear_mps >= 0, "linear_mps", "must be >= 0")
        require(self.angular_radps >= 0, "angular_radps", "must be >= 0")
        require(self.turn_sign in (-1.0, 1.0), "turn_sign", "must be -1 or 1")


class LeaderDecision(NamedTuple):
    rule: int
    """Which branch fired: 1..6 the paper's if/else-if branches in order, 7 the else."""
    linear_mps: float
    angular: float
    """The paper's angularVel (its sign, before ``turn_sign``) [rad/s]."""


def leader_rule(regions: Regions, p: PaperLeaderParams) -> LeaderDecision:
    """Algorithm 1 exactly in the paper's order; strict comparisons as printed, so a
    distance equal to a threshold falls through to the next branch."""
    s = p.scale
    near, fright_clear = p.near_m * s, p.fright_clear_m * s
    front, fleft, fright = regions.front, regions.fleft, regions.fright
    v, w = p.linear_mps, p.angular_radps
    if front > near and fleft > near and fright > fright_clear:
        return LeaderDecision(1, v, 0.0)
    if front < p.front_far_m * s and fleft < p.fleft_far_m * s and fright > fright_clear:
        return LeaderDecision(2, v, 0.0)
    if front < near and fleft < near and fright < near:
        return LeaderDecision(3, 0.0, -w)
    if front < near and fleft > near and fright < near:
        return LeaderDecision(4, 0.0, -w)
    if fright > p.fright_wide_m * s and front > near and fleft > near:
        return LeaderDecision(5, 0.0, w)
    if fright < fright_clear and front > near and fleft > near:
        return LeaderDecision(6, 0.0, -w)
    return LeaderDecision(7, 0.0, 0.0)


@CONTROLLERS.register("paper_leader")
class PaperLeader:
    """Algorithm 1: five scan regions, six if/else-if rules and an else (stop).

    Without a scan it stops. ``last_regions`` and ``last_rule`` expose the latest
    decision for logging and tests.
    """

    Params: ClassVar[type[PaperLeaderParams]] = PaperLeaderParams
    reads_link_ahead: ClassVar[bool] = False

    def __init__(self, params: PaperLeaderParams | None = None):
        self.params = params or PaperLeaderParams()
        self.last_regions: Regions | None = None
        self.last_rule = 0

    def reset(self) -> None:
        self.last_regions = None
        self.last_rule = 0

    def step(self, observation: Observation) -> Command:
        scan = observation.scan
        if scan is None:
            self.last_regions, self.last_rule = None, 0
            return Command(speed_mps=0.0, yaw_rate_radps=0.0)
        regions = region_minima(scan.ranges, scan.range_min)
        decision = leader_rule(regions, self.params)
        self.last_regions, self.last_rule = regions, decision.rule
        return Command(
            speed_mps=decision.linear_mps,
            yaw_rate_radps=self.params.turn_sign * decision.angular,
        )


# ----------------------------------------------------------------------------- follower


class Target(NamedTuple):
    """The predecessor's rear as Algorithm 2 finds it, in the sensor frame (x ahead, y left)."""

    x_m: float
    y_m: float
    distance_m: float
    """``distClose``: sensor to the midpoint of the two edge points [m]."""
    bearing_rad: float
    """``theta = atan2(y, x)``: positive to the left."""
    first: int
    last: int
    """Scan indices of the right and left edge points (the object's ends)."""
    width_m: float
    """Distance between the two edge points (the visible width of the object)."""


def follower_ranges(scan: LaserScan) -> FloatArray:
    """Ranges as Algorithm 2 uses them: ``-inf`` (closer than range_min) becomes
    ``range_min`` (the closest the sensor can measure); ``NaN`` dropouts become ``+inf``
    (no return, like a ray that missed); ``+inf`` stays infinitely far."""
    r = np.asarray(scan.ranges, dtype=np.float64)
    r = np.where(r == -np.inf, scan.range_min, r)
    return np.where(np.isnan(r), np.inf, r)


def discontinuities(ranges: FloatArray, jump_threshold_m: float) -> NDArray[np.intp]:
    """Indices i with ``|r[i+1] - r[i]| > jump_threshold_m`` (lines 1-5, both directions).

    ``+inf`` is infinitely far, so a step between a return and no return is always a
    jump; ``inf -> inf`` (inf - inf is NaN) is not.
    """
    r = np.asarray(ranges, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        jump = np.abs(np.diff(r))
    return np.flatnonzero(jump > jump_threshold_m)


def find_predecessor(
    scan: LaserScan,
    jump_threshold_m: float,
    fov_edges: bool = True,
    min_width_m: float = 0.0,
    max_width_m: float = math.inf,
) -> Target | None:
    """Lines 1-19 of Algorithm 2: the nearest object between two discontinuities.

    The discontinuities cut the scan into runs; a run of valid returns bounded on both
    sides by a discontinuity (or, with ``fov_edges``, by the end of the scan) is an
    object. Its edge points are the near-side samples of the bounding discontinuities
    (``laser(diff+1)`` after a falling step, ``laser(diff)`` before a rising one), turned
    into cartesian points with each ray's own ANGLE; the object's rear is their midpoint.
    Objects whose edge-to-edge width is outside ``[min_width_m, max_width_m]`` are
    skipped; of the rest the one with the smallest ``distClose`` is the predecessor.
    """
    r = follower_ranges(scan)
    n = r.size
    cuts = discontinuities(r, jump_threshold_m)
    starts = np.concatenate(([0], cuts + 1))
    stops = np.concatenate((cuts, [n - 1]))  # inclusive
    angles = scan.angles
    best: Target | None = None
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        if not (np.isfinite(r[a]) and np.isfinite(r[b])):
            continue  # background (no return) or a run touching it without a step
        if not fov_edges and (a == 0 or b == n - 1):
            continue  # an end of the run is the end of the field of view, not a step
        ra, rb, ta, tb = float(r[a]), float(r[b]), float(angles[a]), float(angles[b])
        x1, y1 = ra * math.cos(ta), ra * math.sin(ta)
        x2, y2 = rb * math.cos(tb), rb * math.sin(tb)
        width = math.hypot(x2 - x1, y2 - y1)
        if not min_width_m <= width <= max_width_m:
            continue
        x, y = 0.5 * (x1 + x2), 0.5 * (y1 + y2)
        dist = math.hypot(x, y)
        if best is None or dist < best.distance_m:
            best = Target(x, y, dist, math.atan2(y, x), a, b, width)
    return best


def arc_length(distance_m: float, theta_rad: float) -> float:
    """Lines 23-24: ``r = d / (2 sin(theta/2))``, ``linvel = r * theta``, i.e. the arc of
    central angle theta on the chord d; equal to d in the limit theta -> 0."""
    half = 0.5 * theta_rad
    if abs(half) < 1e-9:
        return distance_m
    return distance_m * half / math.sin(half)


@dataclass(frozen=True)
class PaperFollowerParams:
    """Algorithm 2's constants and the readings it needs to become a velocity command."""

    jump_threshold_m: float = bounded(0.5, gt=0, le=1000)
    """Line 2: consecutive ranges differing by more than this are a discontinuity [m]."""
    stand_off_m: float = bounded(0.1, ge=0, le=1000)
    """Line 20: move only while ``distClose > stand_off_m``, else stop [m]. The paper's
    0.1 m is below the paper's follower range_min (0.3 m): see docs/paper.md."""
    arc_time_s: float = bounded(1.0, gt=0, le=100)
    """Line 24's ``linvel = r * theta`` is a length; speed = that arc / ``arc_time_s``."""
    angular_gain_per_s: float = bounded(1.0, ge=0, le=100)
    """Line 22 read in SI: yaw rate = gain x bearing theta [1/s]."""
    fov_edges: bool = True
    """The ends of the field of view bound an object like a discontinuity does (a
    0.25 m wide predecessor fills the +-11.5 deg view when closer than 0.61 m)."""
    min_width_m: float = bounded(0.0, ge=0, le=100)
    """Objects narrower than this (edge to edge) are not the predecessor [m]."""
    max_width_m: float = bounded(math.inf, gt=0, le=100, allow_inf=True)
    """Objects wider than this are not the predecessor [m] (the paper measures the
    predecessor's width but states no bound: no filter by default)."""
    max_speed_mps: float = bounded(math.inf, gt=0, le=150, allow_inf=True)
    """Optional cap on the commanded speed [m/s] (the vehicle model applies its own)."""

    def __post_init__(self) -> None:
        require(self.jump_threshold_m > 0, "jump_threshold_m", "must be > 0 [m]")
        require(self.stand_off_m >= 0, "stand_off_m", "must be >= 0 [m]")
        require(self.arc_time_s > 0, "arc_time_s", "must be > 0 [s]")
        require(self.angular_gain_per_s >= 0, "angular_gain_per_s", "must be >= 0 [1/s]")
        require(self.min_width_m >= 0, "min_width_m", "must be >= 0 [m]")
        require(self.max_width_m > self.min_width_m, "max_width_m", "must be > min_width_m")
        require(self.max_speed_mps > 0, "max_speed_mps", "must be > 0 [m/s]")


@CONTROLLERS.register("paper_follower")
class PaperFollower:
    """Algorithm 2: find the predecessor's rear from range discontinuities, steer toward
    its bearing, drive the arc to it; stop when it is within the stand-off or not seen.

    ``last_target`` exposes the latest detection (None: not seen) for logging and tests.
    """

    Params: ClassVar[type[PaperFollowerParams]] = PaperFollowerParams
    reads_link_ahead: ClassVar[bool] = False

    def __init__(self, params: PaperFollowerParams | None = None):
        self.params = params or PaperFollowerParams()
        self.last_target: Target | None = None

    def reset(self) -> None:
        self.last_target = None

    def step(self, observation: Observation) -> Command:
        p = self.params
        scan = observation.scan
        target = None
        if scan is not None:
            target = find_predecessor(
                scan, p.jump_threshold_m, p.fov_edges, p.min_width_m, p.max_width_m
            )
        self.last_target = target
        if target is None or not target.distance_m > p.stand_off_m:
            return Command(speed_mps=0.0, yaw_rate_radps=0.0)
        theta = target.bearing_rad
        speed = min(arc_length(target.distance_m, theta) / p.arc_time_s, p.max_speed_mps)
        return Command(speed_mps=speed, yaw_rate_radps=p.angular_gain_per_s * theta)
