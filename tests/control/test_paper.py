"""The paper's Algorithm 1 (leader) and Algorithm 2 (follower) on synthetic scans (no SUMO).

Scenes are built from segments and boxes and scanned with ``cast_rays``, so the
controllers see exactly what the co-simulation would give them.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from platoon_sumo.config_loader import FieldError
from platoon_sumo.control import CONTROLLERS
from platoon_sumo.control.base import Command, Observation
from platoon_sumo.control.paper import (
    PaperFollower,
    PaperFollowerParams,
    PaperLeader,
    PaperLeaderParams,
    Regions,
    arc_length,
    discontinuities,
    find_predecessor,
    leader_rule,
    region_bounds,
    region_minima,
)
from platoon_sumo.path import RoutePath
from platoon_sumo.sensors.laser import LaserConfig, LaserScan
from platoon_sumo.sensors.raycast import cast_rays
from platoon_sumo.vehicles import KinematicState, MotionLimits, Unicycle

ROBOT_LENGTH_M, ROBOT_WIDTH_M = 0.30, 0.25
FRONT_OFFSET_M = 0.15  # wheel axle (the reference point) to front bumper
LIMITS = MotionLimits(max_speed_mps=0.3, max_accel_mps2=0.5, max_decel_mps2=1.0,
                      max_yaw_rate_radps=1.5)  # fmt: skip
DT = 0.05
_STRAIGHT = RoutePath.from_pieces(
    [np.column_stack([np.linspace(-5, 100, 211), np.zeros(211)])], ["e_0"], [0.5], [0.5], 0.5
)
#: Follower parameters tuned for the paper's robots (docs/paper.md, "Parameters"): the
#: paper's 0.1 m stand-off lies inside the follower's 0.3 m blind zone, and its
#: linvel = arc length / 1 s would close to 0.1 m at the leader's 0.1 m/s.
TUNED_FOLLOWER = PaperFollowerParams(stand_off_m=0.35, arc_time_s=4.0)
STOP = Command(speed_mps=0.0, yaw_rate_radps=0.0)


def observe(scan: LaserScan | None, x=0.0, y=0.0, yaw=0.0, v=0.0, t=0.0) -> Observation:
    return Observation(
        time_s=t, dt_s=DT, vehicle_id="r", role="follower", x_m=x, y_m=y, yaw_rad=yaw,
        speed_mps=v, front_offset_m=FRONT_OFFSET_M, length_m=ROBOT_LENGTH_M,
        width_m=ROBOT_WIDTH_M, limits=LIMITS, path=_STRAIGHT, scan=scan,
    )  # fmt: skip


def scan_of(config: LaserConfig, rectangles=None, segments=None, origin=(0.0, 0.0), heading=0.0):
    ranges = cast_rays(origin, heading, config, rectangles, segments)
    return LaserScan.from_ranges(config, ranges, origin, heading)


def leader_config(samples: int = 720) -> LaserConfig:
    base = LaserConfig.preset("paper_leader")
    return LaserConfig.preset("paper_leader", samples=samples) if samples != base.samples else base


# ----------------------------------------------------------------------------- leader

_REGION_CENTRE_DEG = {"right": -72.0, "fright": -36.0, "front": 0.0, "fleft": 36.0, "left": 72.0}


def region_walls(**distances: float) -> np.ndarray:
    """One short wall per named region, perpendicular to the region's centre ray at the
    given distance and spanning +-10 deg of it, so that region's minimum is that distance."""
    segs = []
    for name, d in distances.items():
        a = math.radians(_REGION_CENTRE_DEG[name])
        half = d * math.tan(math.radians(10.0))
        cx, cy = d * math.cos(a), d * math.sin(a)
        tx, ty = -math.sin(a), math.cos(a)
        segs.append([cx - half * tx, cy - half * ty, cx + half * tx, cy + half * ty])
    return np.array(segs)


def test_regions_are_the_papers_index_ranges_for_720_samples():
    assert region_bounds(720) == [(0, 144), (144, 288), (288, 432), (432, 576), (576, 720)]
    assert region_bounds(360) == [(0, 72), (72, 144), (144, 216), (216, 288), (288, 360)]
    bounds = region_bounds(101)
    assert bounds[0][0] == 0 and bounds[-1][1] == 101
    assert all(a[1] == b[0] for a, b in itertools.pairwise(bounds))
    assert {b - a for a, b in bounds} <= {20, 21}


def test_region_minimum_counts_only_valid_readings():
    r = np.full(10, np.inf)
    r[0], r[1] = 2.0, np.nan  # right: a reading and a dropout
    r[2], r[3] = -np.inf, 1.5  # fright: closer than range_min counts as range_min
    r[4], r[5] = np.nan, np.inf  # front: nothing valid
    r[6], r[7] = 0.9, 0.8  # fleft
    regions = region_minima(r, range_min_m=0.3)
    assert regions == Regions(right=2.0, fright=0.3, front=math.inf, fleft=0.8, left=math.inf)


@pytest.mark.parametrize("samples", [720, 360, 101])
def test_region_minima_of_a_cast_scene(samples):
    config = leader_config(samples)
    scan = scan_of(config, segments=region_walls(right=0.4, fright=0.6, front=1.2, fleft=2.5))
    regions = region_minima(scan.ranges, scan.range_min)
    assert regions.right == pytest.approx(0.4, abs=2e-3)
    assert regions.fright == pytest.approx(0.6, abs=2e-3)
    assert regions.front == pytest.approx(1.2, abs=2e-3)
    assert regions.fleft == pytest.approx(2.5, abs=2e-3)
    assert regions.left == math.inf


# Scenes (region minima in metres) that reach each branch of Algorithm 1 with the paper's
# thresholds, and the paper's (linearVel, angularVel) for it.
LEADER_BRANCHES = [
    (1, dict(front=1.5, fleft=1.5, fright=0.6), 0.1, 0.0),
    (1, dict(fright=0.6), 0.1, 0.0),  # open space ahead: nothing seen is +inf
    (2, dict(front=0.8, fleft=2.0, fright=0.6), 0.1, 0.0),
    (3, dict(front=0.8, fleft=0.8, fright=0.4), 0.0, -0.1),
    (2, dict(front=0.8, fleft=0.8, fright=0.8), 0.1, 0.0),  # rule 2 shadows 3 if Fright > 0.5
    (4, dict(front=0.8, fleft=1.5, fright=0.4), 0.0, -0.1),
    (4, dict(front=0.8, fright=0.8), 0.0, -0.1),  # Fleft > 3: rule 2 does not apply
    (6, dict(front=1.5, fleft=1.5, fright=0.4), 0.0, -0.1),
    (7, dict(front=1.5, fleft=0.8, fright=0.4), 0.0, 0.0),
]


@pytest.mark.parametrize("samples", [720, 360])
@pytest.mark.parametrize(("rule", "walls", "linear", "angular"), LEADER_BRANCHES)
def test_each_leader_branch_gives_the_papers_command(samples, rule, walls, linear, angular):
    ctrl = PaperLeader()  # turn_sign = -1: the paper's angularVel < 0 is a LEFT turn
    ctrl.reset()
    cmd = ctrl.step(observe(scan_of(leader_config(samples), segments=region_walls(**walls))))
    assert ctrl.last_rule == rule
    assert cmd.speed_mps == pytest.approx(linear)
    assert cmd.yaw_rate_radps == pytest.approx(-angular)


def test_turn_sign_plus_one_is_the_literal_ros_sign():
    scene = scan_of(leader_config(), segments=region_walls(front=1.5, fleft=1.5, fright=0.4))
    literal = PaperLeader(PaperLeaderParams(turn_sign=1.0)).step(observe(scene))
    faithful = PaperLeader().step(observe(scene))
    assert literal.yaw_rate_radps == pytest.approx(-0.1)  # clockwise: toward the close wall
    assert faithful.yaw_rate_radps == pytest.approx(0.1)  # counter-clockwise: away from it


def test_rule_5_is_shadowed_by_rule_1_with_the_papers_thresholds():
    p = PaperLeaderParams()
    grid = [0.2, 0.45, 0.55, 0.65, 0.75, 0.9, 1.1, 1.5, 2.5, 3.5, math.inf]
    rules = {
        leader_rule(Regions(math.inf, fr, f, fl, math.inf), p).rule
        for fr in grid
        for f in grid
        for fl in grid
    }
    assert rules == {1, 2, 3, 4, 6, 7}
    # It is reachable only if its 0.7 m is below rule 1's 0.5 m (parameters reordered):
    reordered = PaperLeaderParams(fright_clear_m=0.9, fright_wide_m=0.7)
    decision = leader_rule(Regions(math.inf, 0.8, 1.5, 1.5, math.inf), reordered)
    assert decision == (5, 0.0, 0.1)


def test_thresholds_scale_together():
    walls = dict(front=0.6, fleft=0.6, fright=0.35)
    scan = scan_of(leader_config(), segments=region_walls(**walls))
    assert leader_rule(region_minima(scan.ranges, scan.range_min), PaperLeaderParams()).rule == 3
    half = PaperLeaderParams(scale=0.5)  # near 0.5 m, Fright clearance 0.25 m
    assert leader_rule(region_minima(scan.ranges, scan.range_min), half).rule == 1


def test_leader_without_scan_stops():
    assert PaperLeader().step(observe(None)) == STOP


def test_leader_params_are_checked():
    with pytest.raises(FieldError):
        PaperLeaderParams(turn_sign=0.5)
    with pytest.raises(FieldError):
        PaperLeaderParams(scale=0.0)


def _paper_world_leader_run(params: PaperLeaderParams, seconds: float):
    """The leader alone in networks/paper_world (walls only, no SUMO) from the start of
    loop_outer in lane 0; returns (time, lateral offset of the bumper, route s) per step."""
    from platoon_sumo.sumo.network import Network
    from platoon_sumo.sumo.shapes import read_wall_segments

    world = Path(__file__).resolve().parents[2] / "networks" / "paper_world"
    walls = read_wall_segments([world / "walls.add.xml"])
    path = Network(world / "paper_world.net.xml").route_path(
        ["SW_S", "S_SE", "SE_NE", "NE_N"], 0.05, first_lane=0
    )
    config = leader_config()
    s0 = 3.4
    fx, fy = path.point_at(s0)
    h = path.heading_at(s0)
    state = KinematicState.of(
        fx - FRONT_OFFSET_M * math.cos(h), fy - FRONT_OFFSET_M * math.sin(h), h, 0
    )
    ctrl, model = PaperLeader(params), Unicycle()
    ctrl.reset()
    log, s_hint = [], s0
    for k in range(int(seconds / DT)):
        x, y, yaw = float(state.x_m[0]), float(state.y_m[0]), float(state.yaw_rad[0])
        bumper = (x + FRONT_OFFSET_M * math.cos(yaw), y + FRONT_OFFSET_M * math.sin(yaw))
        scan = scan_of(config, segments=walls, origin=bumper, heading=yaw)
        cmd = ctrl.step(observe(scan, x, y, yaw, float(state.speed_mps[0]), k * DT))
        where = path.project(*bumper, s_hint_m=s_hint, window_m=1.0)
        s_hint = where.s_m
        log.append((k * DT, where.lateral_offset_m, where.s_m))
        state = model.step(state, np.array([cmd.speed_mps]), np.array([cmd.yaw_rate_radps]),
                           LIMITS, DT)  # fmt: skip
    return np.array(log)


def test_leader_turns_the_first_corner_of_paper_world_in_the_right_lane():
    log = _paper_world_leader_run(PaperLeaderParams(), seconds=150.0)
    _, offset, s = log.T
    assert s[-1] > 14.0, "through the SE corner and up SE_NE"
    assert np.abs(offset).max() < 0.15  # a lane is 0.5 m wide


def test_literal_ros_sign_leaves_the_lane_in_paper_world():
    log = _paper_world_leader_run(PaperLeaderParams(turn_sign=1.0), seconds=90.0)
    _, offset, s = log.T
    assert np.abs(offset).max() > 0.25 or s[-1] < 9.0


# ----------------------------------------------------------------------------- follower

FOLLOWER = LaserConfig.preset("paper_follower")


def box_ahead(rear_x: float, y: float = 0.0, yaw: float = 0.0) -> np.ndarray:
    """A 0.3 x 0.25 m robot whose rear centre is at (rear_x, y), heading yaw."""
    cx = rear_x + 0.5 * ROBOT_LENGTH_M * math.cos(yaw)
    cy = y + 0.5 * ROBOT_LENGTH_M * math.sin(yaw)
    return np.array([[cx, cy, yaw, ROBOT_LENGTH_M, ROBOT_WIDTH_M]])


def follower_step(params: PaperFollowerParams, rectangles=None, segments=None):
    ctrl = PaperFollower(params)
    ctrl.reset()
    cmd = ctrl.step(observe(scan_of(FOLLOWER, rectangles, segments)))
    return cmd, ctrl.last_target


def test_discontinuities_count_steps_to_and_from_no_return():
    r = np.array([np.inf, np.inf, 0.6, 0.61, 0.62, np.inf, 0.9, 0.3, 0.95, np.inf])
    assert discontinuities(r, 0.5).tolist() == [1, 4, 5, 6, 7, 8]


def test_arc_length_is_the_distance_in_the_straight_limit():
    assert arc_length(0.6, 0.0) == 0.6
    assert arc_length(0.6, 1e-12) == pytest.approx(0.6)
    assert arc_length(0.6, 0.2) == pytest.approx(0.6 * 0.1 / math.sin(0.1))
    assert arc_length(0.6, -0.2) == arc_length(0.6, 0.2)


def test_predecessor_straight_ahead_drives_straight():
    cmd, target = follower_step(PaperFollowerParams(), box_ahead(0.6))
    assert target is not None
    assert target.distance_m == pytest.approx(0.6, abs=1e-3)
    assert cmd.speed_mps == pytest.approx(0.6, abs=1e-3)  # arc / arc_time_s (1 s)
    assert abs(cmd.yaw_rate_radps) < 1e-3
    tuned, _ = follower_step(TUNED_FOLLOWER, box_ahead(0.6))
    assert tuned.speed_mps == pytest.approx(0.15, abs=1e-3)


def test_fully_visible_predecessor_is_found_between_two_discontinuities():
    cmd, target = follower_step(PaperFollowerParams(fov_edges=False), box_ahead(0.8))
    assert target is not None and target.first > 0 and target.last < FOLLOWER.samples - 1
    assert target.width_m == pytest.approx(ROBOT_WIDTH_M, abs=0.01)
    assert target.distance_m == pytest.approx(0.8, abs=1e-3)
    assert cmd.speed_mps > 0


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_offset_predecessor_turns_the_follower_toward_it(side):
    cmd, target = follower_step(PaperFollowerParams(), box_ahead(0.7, y=side * 0.08))
    assert target is not None
    assert cmd.speed_mps > 0
    assert math.copysign(1.0, cmd.yaw_rate_radps) == side
    assert cmd.yaw_rate_radps == pytest.approx(target.bearing_rad)


def test_turning_predecessor_is_still_tracked():
    cmd, target = follower_step(PaperFollowerParams(), box_ahead(0.65, y=0.03, yaw=0.6))
    assert target is not None and 0.55 < target.distance_m < 0.8
    assert cmd.speed_mps > 0 and cmd.yaw_rate_radps > 0


def test_predecessor_at_the_edge_of_the_view_is_tracked_with_fov_edges():
    # Only its right part is inside the +-11.5 deg view: the run ends at the last ray.
    rect = box_ahead(0.7, y=0.2)
    cmd, target = follower_step(PaperFollowerParams(), rect)
    assert target is not None and target.last == FOLLOWER.samples - 1
    assert cmd.speed_mps > 0 and cmd.yaw_rate_radps > 0
    strict, none = follower_step(PaperFollowerParams(fov_edges=False), rect)
    assert none is None and strict == STOP


def test_close_predecessor_filling_the_view_needs_fov_edges():
    # At 0.5 m a 0.25 m wide robot covers more than +-11.5 deg: no discontinuity at all.
    _, target = follower_step(PaperFollowerParams(), box_ahead(0.5))
    assert target is not None and (target.first, target.last) == (0, FOLLOWER.samples - 1)
    _, none = follower_step(PaperFollowerParams(fov_edges=False), box_ahead(0.5))
    assert none is None


def test_partially_occluded_predecessor_is_still_tracked():
    # A 5 cm post 0.5 m ahead hides the right part of a predecessor 0.8 m ahead. The
    # depth step post -> robot (0.3 m) is below the 0.5 m jump threshold, so the post and
    # the visible part of the robot form one object: its ends are the post's right side
    # and the robot's left side, and the target lies between them.
    post = np.array([[0.525, -0.06, 0.0, 0.05, 0.05]])
    rects = np.vstack([box_ahead(0.8), post])
    cmd, target = follower_step(PaperFollowerParams(), rects)
    assert target is not None and 0.5 < target.distance_m < 0.8
    assert abs(target.bearing_rad) < math.radians(5.0)
    assert cmd.speed_mps > 0


def test_a_dropout_splits_the_object_and_the_nearer_part_wins():
    scan = scan_of(FOLLOWER, box_ahead(0.8))
    ranges = scan.ranges.copy()
    ranges[400] = np.nan  # one lost return inside the robot: read as no return
    whole = find_predecessor(scan, 0.5)
    split = find_predecessor(LaserScan.from_ranges(FOLLOWER, ranges, (0, 0), 0.0), 0.5)
    assert whole is not None and split is not None
    assert split.first == whole.first and split.last == 399
    assert split.bearing_rad < whole.bearing_rad


def test_width_filter_skips_a_wall():
    wall = np.array([[0.5, -1.0, 0.5, 1.0]])  # fills the whole view at 0.5 m
    _, target = follower_step(PaperFollowerParams(), box_ahead(0.8), segments=wall)
    assert target is not None and target.distance_m == pytest.approx(0.5, abs=1e-3)
    _, target = follower_step(PaperFollowerParams(max_width_m=0.15), segments=wall)
    assert target is None


def test_no_predecessor_stops():
    cmd, target = follower_step(PaperFollowerParams())
    assert target is None and cmd == STOP
    assert PaperFollower().step(observe(None)) == STOP


def test_predecessor_beyond_range_is_not_seen_and_stops():
    cmd, target = follower_step(PaperFollowerParams(), box_ahead(1.1))
    assert target is None and cmd.speed_mps == 0.0 and cmd.yaw_rate_radps == 0.0


def test_predecessor_within_stand_off_stops():
    cmd, target = follower_step(TUNED_FOLLOWER, box_ahead(0.32))
    assert target is not None and target.distance_m < TUNED_FOLLOWER.stand_off_m
    assert cmd.speed_mps == 0.0 and cmd.yaw_rate_radps == 0.0


def test_papers_stand_off_is_inside_the_blind_zone():
    # Closer than range_min (0.3 m) the scan reads -inf, taken as range_min: distClose
    # never drops below ~0.29 m, so the paper's `distClose > 0.1` always lets it drive.
    cmd, target = follower_step(PaperFollowerParams(), box_ahead(0.2))
    assert target is not None and target.distance_m > 0.28
    assert cmd.speed_mps > 0.28


def test_follower_params_are_checked():
    with pytest.raises(FieldError):
        PaperFollowerParams(arc_time_s=0.0)
    with pytest.raises(FieldError):
        PaperFollowerParams(min_width_m=0.3, max_width_m=0.2)


def _follow(predecessor_yaw_rate: float, seconds: float = 60.0):
    """A follower unicycle behind a scripted 0.1 m/s predecessor box; per step the true
    bumper-to-rear gap and whether the predecessor was seen."""
    speed = 0.1
    pred = np.array([0.0, 0.0, 0.0])  # rear centre x, y, yaw
    gap0 = 0.5
    state = KinematicState.of(-gap0 - FRONT_OFFSET_M, 0.0, 0.0, 0.0)
    ctrl, model = PaperFollower(TUNED_FOLLOWER), Unicycle()
    ctrl.reset()
    gaps, seen = [], []
    for k in range(int(seconds / DT)):
        x, y, yaw = float(state.x_m[0]), float(state.y_m[0]), float(state.yaw_rad[0])
        bumper = (x + FRONT_OFFSET_M * math.cos(yaw), y + FRONT_OFFSET_M * math.sin(yaw))
        rect = box_ahead(pred[0], pred[1], pred[2])
        scan = scan_of(FOLLOWER, rect, origin=bumper, heading=yaw)
        cmd = ctrl.step(observe(scan, x, y, yaw, float(state.speed_mps[0]), k * DT))
        gaps.append(math.hypot(pred[0] - bumper[0], pred[1] - bumper[1]))
        seen.append(ctrl.last_target is not None)
        state = model.step(state, np.array([cmd.speed_mps]), np.array([cmd.yaw_rate_radps]),
                           LIMITS, DT)  # fmt: skip
        pred += (speed * math.cos(pred[2]) * DT, speed * math.sin(pred[2]) * DT,
                 predecessor_yaw_rate * DT)  # fmt: skip
    return np.array(gaps), np.array(seen)


def test_closed_loop_follows_a_straight_predecessor_for_60_s():
    gaps, seen = _follow(0.0)
    assert seen.all()
    assert TUNED_FOLLOWER.stand_off_m < gaps.min() and gaps.max() < 1.0
    assert gaps[-1] == pytest.approx(0.1 * TUNED_FOLLOWER.arc_time_s, abs=0.02)  # v = d / T


def test_closed_loop_follows_a_turning_predecessor():
    gaps, seen = _follow(0.05)  # 2 m radius at 0.1 m/s, half a circle in 60 s
    assert seen.all()
    assert TUNED_FOLLOWER.stand_off_m < gaps.min() and gaps.max() < 1.0


def test_both_are_registered():
    assert CONTROLLERS.get("paper_leader") is PaperLeader
    assert CONTROLLERS.get("paper_follower") is PaperFollower
