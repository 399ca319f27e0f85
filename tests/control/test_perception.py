"""Scan segmentation, rear fitting and the rear tracker on synthetic scans (no SUMO)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from platoon_sumo.control.perception import (
    PerceptionParams,
    RearTracker,
    SensorPose,
    TrackerParams,
    detect_rears,
    segment_scan,
)
from platoon_sumo.sensors.laser import LaserConfig, LaserScan
from platoon_sumo.sensors.raycast import cast_rays

CAR = LaserConfig.preset("utm30lx")
ROBOT = LaserConfig(-math.radians(11.5), math.radians(11.5), 720, 0.3, 1.0)
P = PerceptionParams()
P_ROBOT = PerceptionParams(break_abs_m=0.03, corner_abs_m=0.01)


def box(rear_x: float, rear_y: float, yaw: float = 0.0, length=4.5, width=1.8) -> list[float]:
    """Rectangle whose rear-face centre is at (rear_x, rear_y)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return [rear_x + 0.5 * length * c, rear_y + 0.5 * length * s, yaw, length, width]


def scan(rects, segments=None, config=CAR, origin=(0.0, 0.0), heading=0.0, rng=None, t=0.0):
    ranges = cast_rays(origin, heading, config, rects or None, segments, rng)
    return LaserScan.from_ranges(config, ranges, origin, heading, t)


def big(seg, n=3):
    """Number of clusters with at least n points."""
    return int(((seg.stops - seg.starts) >= n).sum())


def test_clusters_split_on_range_jumps_and_invalid_samples():
    # two cars side by side at different ranges: two clusters (the second car's side,
    # seen at a grazing angle, falls apart into single points)
    seg = segment_scan(scan([box(10.0, 0.0), box(14.0, 3.0)]), P)
    assert big(seg) == 2
    # a car in front of a wall: the wall is cut in two by the car's shadow
    wall = [[20.0, -10.0, 20.0, 10.0]]
    seg = segment_scan(scan([box(10.0, 0.0)], wall), P)
    assert len(seg) == 3
    sizes = np.diff(np.column_stack([seg.starts, seg.stops]), axis=1).ravel()
    assert sizes.sum() == seg.points.shape[0]
    # two cars at the same range with a gap between them (+inf rays): two clusters
    seg = segment_scan(scan([box(10.0, -1.5), box(10.0, 1.5)]), P)
    assert big(seg) == 2
    # one dropout inside a car is bridged, an -inf reading is not
    s = scan([box(10.0, 0.0)])
    ranges = s.ranges.copy()
    hit = np.flatnonzero(np.isfinite(ranges))
    mid = hit[len(hit) // 2]
    ranges[mid] = np.nan
    assert len(segment_scan(LaserScan.from_ranges(CAR, ranges, (0, 0), 0.0), P)) == 1
    ranges[mid] = -np.inf
    assert len(segment_scan(LaserScan.from_ranges(CAR, ranges, (0, 0), 0.0), P)) == 2
    # no hits at all
    assert len(segment_scan(scan([]), P)) == 0


def test_segmentation_break_grows_with_range():
    """A 0.5 m step in depth splits at 10 m; the same relative step does not at 0.5 m."""
    near = [[0.5, -0.2, 0.5, 0.0], [0.51, 0.0, 0.51, 0.2]]  # 1 cm step at 0.5 m
    assert len(segment_scan(scan([], near, config=ROBOT), P_ROBOT)) == 1
    far = [[10.0, -0.6, 10.0, 0.0], [10.5, 0.0, 10.5, 0.6]]  # 0.5 m step at 10 m
    assert len(segment_scan(scan([], far), P)) == 2


@pytest.mark.parametrize(
    ("rear_x", "rear_y", "yaw"),
    [(10.0, 0.0, 0.0), (12.0, 1.0, 0.0), (25.0, -1.5, 0.0), (10.0, 0.5, 0.35), (8.0, -2.0, -0.6)],
)
def test_rear_centre_of_a_car(rear_x, rear_y, yaw):
    cands = detect_rears(scan([box(rear_x, rear_y, yaw)]), P, 1.8, heading_hint_rad=yaw)
    best = next(c for c in cands if not c.alternative)
    assert math.hypot(best.x_m - rear_x, best.y_m - rear_y) < 0.04
    assert best.heading_rad == pytest.approx(yaw, abs=0.03)
    assert best.width_m == pytest.approx(1.8, abs=0.05)
    assert best.l_shape == (yaw != 0.0)
    assert best.range_m == pytest.approx(math.hypot(best.x_m, best.y_m))


def test_rear_centre_with_noise():
    rng = np.random.default_rng(3)
    noisy = LaserConfig.preset("utm30lx", noise_std_m=0.01)
    errors = []
    for _ in range(20):
        cands = detect_rears(scan([box(10.0, 0.3, 0.2)], config=noisy, rng=rng), P, 1.8, 0.2)
        best = next(c for c in cands if not c.alternative)
        errors.append(math.hypot(best.x_m - 10.0, best.y_m - 0.3))
    assert max(errors) < 0.06


def test_partially_occluded_rear_uses_the_expected_width():
    # a nearer car hides the left half of the rear: the visible part is ~1 m wide
    lead = box(12.0, 0.0)
    blocker = box(6.0, 1.45)
    cands = detect_rears(scan([lead, blocker]), P, 1.8)
    far = min(cands, key=lambda c: abs(c.x_m - 12.0))
    assert not far.complete and far.width_m < 1.6
    assert math.hypot(far.x_m - 12.0, far.y_m) < 0.05
    # the middle of the visible part would be off by more than 0.1 m
    assert abs(float(far.points[:, 1].mean())) > 0.1


def test_rear_cut_by_the_field_of_view_at_robot_scale():
    # paper-like follower scan (+-11.5 deg): a robot 0.6 m ahead, 8 cm to the left, is cut
    # by the right edge of the field of view; its left edge is a true edge
    # (its right side is visible too: an L-shape whose corner is a true edge)
    cands = detect_rears(scan([box(0.6, 0.16, 0.0, 0.3, 0.25)], config=ROBOT), P_ROBOT, 0.25)
    best = next(c for c in cands if not c.alternative)
    assert best.l_shape and not best.complete
    assert math.hypot(best.x_m - 0.6, best.y_m - 0.16) < 0.01
    # fully visible, straight ahead
    cands = detect_rears(scan([box(0.7, 0.0, 0.0, 0.3, 0.25)], config=ROBOT), P_ROBOT, 0.25)
    assert cands[0].complete and math.hypot(cands[0].x_m - 0.7, cands[0].y_m) < 0.005
    assert cands[0].width_m == pytest.approx(0.25, abs=0.002)


def test_walls_are_not_rears_and_roi_limits_the_work():
    wall = [[15.0, -10.0, 15.0, 10.0]]
    assert detect_rears(scan([], wall), P, 1.8) == []
    s = scan([box(10.0, 0.0), box(10.0, 6.0)])
    assert len(detect_rears(s, P, 1.8)) == 2
    only = detect_rears(s, P, 1.8, roi=(10.0, 6.0, 1.0))
    assert len(only) == 1 and only[0].y_m == pytest.approx(6.0, abs=0.05)


def test_tracker_converges_to_the_range_rate_of_a_receding_car():
    rng = np.random.default_rng(7)
    noisy = LaserConfig.preset("utm30lx", noise_std_m=0.02)
    tracker = RearTracker(TrackerParams())
    pose = SensorPose(0.0, 0.0, 0.0)
    dt, v = 0.1, 1.5
    for k in range(60):
        t = k * dt
        rear_x = 8.0 + v * t
        s = scan([box(rear_x, 0.0)], config=noisy, rng=rng, t=t)
        cands = detect_rears(s, P, 1.8)
        hit = tracker.step(t, cands, pose, (0.0, 0.0), 0.9)
        assert hit is not None
    assert tracker.confirmed
    x, y = tracker.position
    assert x == pytest.approx(8.0 + v * 5.9, abs=0.05) and abs(y) < 0.05
    vx, vy = tracker.velocity
    assert vx == pytest.approx(v, abs=0.1) and abs(vy) < 0.1


def test_tracker_starts_on_the_rear_closest_to_straight_ahead_and_loses_it():
    p = TrackerParams(max_missed_scans=3, lost_after_s=10.0)
    tracker = RearTracker(p)
    pose = SensorPose(100.0, 50.0, math.pi / 2)  # sensor frame != world frame
    s = scan([box(12.0, 1.0), box(8.0, -1.4), box(6.0, 5.0)])
    cands = detect_rears(s, P, 1.8)
    assert len(cands) == 3
    started = tracker.step(0.0, cands, pose, (0.0, 0.0), 0.9)
    assert started is not None and started.x_m == pytest.approx(12.0, abs=0.05)
    x, y = tracker.position
    assert (x, y) == pytest.approx((99.0, 62.0), abs=0.05)  # world frame
    for k in range(1, 3):  # confirmed on the third hit
        assert not tracker.confirmed
        assert tracker.step(0.1 * k, cands, pose, (0.0, 0.0), 0.9) is started or True
    assert tracker.confirmed
    # gating: the other cars are never associated; after 3 empty scans + 1 it is lost
    others = [c for c in cands if abs(c.x_m - 12.0) > 1.0]
    for k in range(3, 6):
        assert tracker.step(0.1 * k, others, pose, (0.0, 0.0), 0.9) is None
        assert tracker.active
    assert tracker.step(0.6, others, pose, (0.0, 0.0), 0.9) is None
    assert not tracker.active


def test_tracker_loses_a_track_after_the_time_limit():
    tracker = RearTracker(TrackerParams(max_missed_scans=100, lost_after_s=0.5))
    pose = SensorPose(0.0, 0.0, 0.0)
    cands = detect_rears(scan([box(10.0, 0.0)]), P, 1.8)
    for k in range(3):
        tracker.step(0.1 * k, cands, pose, (0.0, 0.0), 0.9)
    assert tracker.confirmed
    tracker.step(0.6, [], pose, (0.0, 0.0), 0.9)
    assert tracker.active
    tracker.step(0.75, [], pose, (0.0, 0.0), 0.9)
    assert not tracker.active
