"""The compiled perception and follower kernels against the numpy implementation they
replaced (``reference_perception.py``, ``reference_laser_follower.py``), on random
scenes: the same clusters, rear candidates, blocked checks, clearances and tracks, to
floating-point rounding."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.control import perception as new
from platoon_sumo.control.laser_follower import LaserFollower, LaserFollowerParams
from platoon_sumo.kernels.follower import start_gate_kernel
from platoon_sumo.kernels.perception import CANDIDATE_COLUMNS
from platoon_sumo.sensors.laser import LaserConfig, LaserScan
from platoon_sumo.sensors.raycast import cast_rays
from tests.control import reference_perception as ref
from tests.control.reference_laser_follower import ReferenceLaserFollower

CAR = LaserConfig.preset("utm30lx")
ROBOT = LaserConfig(-math.radians(60), math.radians(60), 720, 0.3, 2.0)
SCALES = {
    # laser, perception params, vehicle length / width, scene extent
    "car": (CAR, new.PerceptionParams(), 4.5, 1.8, 25.0),
    "robot": (
        ROBOT,
        new.PerceptionParams(break_abs_m=0.03, corner_abs_m=0.01),
        0.3,
        0.25,
        1.8,
    ),
}
TOL = 1e-9


def random_scan(seed: int, scale: str) -> tuple[LaserScan, float, new.PerceptionParams]:
    """Vehicles (some overlapping the field of view's edges, some close), a wall, range
    noise and dropouts, and a few readings forced to -inf / +inf / NaN."""
    laser, params, length, width, extent = SCALES[scale]
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 9))
    rects = [
        [
            rng.uniform(-0.2, 1.0) * extent,
            rng.uniform(-0.6, 0.6) * extent,
            rng.uniform(-math.pi, math.pi),
            length * rng.uniform(0.8, 1.2),
            width * rng.uniform(0.8, 1.2),
        ]
        for _ in range(n)
    ]
    segments = None
    if rng.random() < 0.5:
        x = rng.uniform(0.3, 1.0) * extent
        segments = [[x, -extent, x + rng.uniform(-0.3, 0.3) * extent, extent]]
    noisy = LaserConfig(
        laser.angle_min_rad, laser.angle_max_rad, laser.samples, laser.range_min_m,
        laser.range_max_m, noise_std_m=float(rng.choice([0.0, 0.003, 0.02])),
        dropout_prob=float(rng.choice([0.0, 0.02])),
    )  # fmt: skip
    ranges = cast_rays((0.0, 0.0), 0.0, noisy, rects or None, segments, rng)
    for value in (-np.inf, np.inf, np.nan):
        ranges[rng.integers(0, ranges.size, int(rng.integers(0, 4)))] = value
    scan = LaserScan.from_ranges(noisy, ranges, (0.0, 0.0), 0.0, 0.0)
    return scan, width, params


def assert_same_candidates(got: list, want: list) -> None:
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        assert (a.complete, a.l_shape, a.alternative) == (b.complete, b.l_shape, b.alternative)
        assert abs(a.x_m - b.x_m) < TOL and abs(a.y_m - b.y_m) < TOL
        assert abs(a.width_m - b.width_m) < TOL
        assert abs(math.remainder(a.heading_rad - b.heading_rad, 2 * math.pi)) < TOL
        assert a.points.shape == b.points.shape
        assert np.allclose(a.points, b.points, rtol=0.0, atol=TOL)


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    scale=st.sampled_from(sorted(SCALES)),
    hint=st.floats(-math.pi, math.pi),
    roi=st.one_of(st.none(), st.tuples(st.floats(-2, 30), st.floats(-15, 15), st.floats(0, 8))),
)
@pytest.mark.slow
def test_segmentation_and_rear_detection_match_the_reference(seed, scale, hint, roi):
    scan, width, params = random_scan(seed, scale)
    a, b = new.segment_scan(scan, params), ref.segment_scan(scan, params)
    assert np.array_equal(a.starts, b.starts) and np.array_equal(a.stops, b.stops)
    assert np.array_equal(a.index, b.index)
    assert np.allclose(a.points, b.points, rtol=0.0, atol=TOL)
    got = new.detect_rears(scan, params, width, hint, roi)
    assert_same_candidates(got, ref.detect_rears(scan, params, width, hint, roi))
    _, rows = new.detect_rear_rows(scan, params, width, hint, roi)
    assert len(rows) == len(got)
    # each cluster on its own, with every combination of true ends, with and without
    # the half-ray padding
    for c in range(len(b)):
        cluster = b.cluster(c)
        for first, last, step in ((True, True, 0.0), (False, True, 0.004), (True, False, 0.01)):
            assert_same_candidates(
                new.fit_rear(cluster, first, last, width, hint, params, step),
                ref.fit_rear(cluster, first, last, width, hint, params, step),
            )


def _reference_follower(scan: LaserScan, min_gap_m: float) -> ReferenceLaserFollower:
    follower = ReferenceLaserFollower(LaserFollowerParams(min_gap_m=min_gap_m))
    follower._scan_points = scan.points_world()
    return follower


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    scale=st.sampled_from(sorted(SCALES)),
    min_gap=st.floats(0.0, 3.0),
    pose=st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-math.pi, math.pi)),
    curvature=st.one_of(st.just(0.0), st.floats(-0.5, 0.5)),
)
def test_blocked_check_and_arc_clearance_match_the_reference(seed, scale, min_gap, pose, curvature):
    scan, width, _ = random_scan(seed, scale)
    x, y, yaw = pose
    scan = LaserScan(**{**scan.__dict__, "origin_x_m": x, "origin_y_m": y, "heading_rad": yaw})
    reference = _reference_follower(scan, min_gap)
    follower = LaserFollower(LaserFollowerParams(min_gap_m=min_gap))
    obs = SimpleNamespace(
        x_m=x - 0.5, y_m=y + 0.2, yaw_rad=yaw + 0.1, front_offset_m=1.0, width_m=width,
        time_s=0.0, speed_mps=1.0, length_m=4.5, path=None, lane_offset_m=0.0,
    )  # fmt: skip
    follower._perceive(obs, scan)
    assert follower._blocked == reference._check_blocked(scan, width)
    got = follower._arc_clearance(obs, curvature)
    want = reference._arc_clearance(obs, curvature)
    assert got == want or abs(got - want) < TOL


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), confirm=st.integers(1, 4), missed=st.integers(0, 5))
def test_tracker_matches_the_reference(seed, confirm, missed):
    """Random candidate sequences (jittered rears near a moving target, clutter, gaps,
    incomplete rears, alternatives, repeated and irregular times)."""
    rng = np.random.default_rng(seed)
    tp = dict(confirm_scans=confirm, max_missed_scans=missed, lost_after_s=0.7)
    a, b = new.RearTracker(new.TrackerParams(**tp)), ref.RearTracker(ref.TrackerParams(**tp))
    pose = new.SensorPose(rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-3, 3))
    t, rear = 0.0, np.array([rng.uniform(3, 20), rng.uniform(-1, 1)])
    v = rng.uniform(-2, 2, 2)
    for _ in range(60):
        t += float(rng.choice([0.0, 0.025, 0.1, 0.3]))
        rear = rear + v * 0.1
        cands = []
        for _ in range(int(rng.integers(0, 4))):
            near = rng.random() < 0.7
            cx, cy = rear + rng.normal(0, 0.1 if near else 3.0, 2)
            cands.append(
                new.RearCandidate(
                    float(cx),
                    float(cy),
                    1.8,
                    0.0,
                    bool(rng.random() < 0.7),
                    bool(rng.random() < 0.3),
                    np.zeros((0, 2)),
                    bool(rng.random() < 0.2),
                )
            )
        own_v = tuple(rng.uniform(-1, 1, 2))
        got = a.step(t, cands, pose, own_v, 0.9)
        want = b.step(t, cands, pose, own_v, 0.9)  # type: ignore[arg-type]
        assert got is want
        assert (a.active, a.hits, a.missed, a.confirmed) == (
            b.active,
            b.hits,
            b.missed,
            b.confirmed,
        )
        assert np.allclose(a.x, b.x, rtol=0.0, atol=TOL)
        assert np.allclose(a.P, b.P, rtol=1e-12, atol=TOL)
        assert np.allclose(a.predicted(t + 0.05), b.predicted(t + 0.05), rtol=0.0, atol=TOL)
        assert (
            a.heading_hint(0.3) == b.heading_hint(0.3)
            or abs(a.heading_hint(0.3) - b.heading_hint(0.3)) < TOL
        )
        assert a.last_candidate is b.last_candidate


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(-5.0, 40.0, allow_nan=False),
            st.floats(-6.0, 6.0, allow_nan=False),
            st.booleans(),
        ),
        max_size=12,
    )
)
def test_start_gate_keeps_the_rows_the_tracker_may_start_on(items):
    gate = new.TrackerParams()
    rows = np.zeros((len(items), len(CANDIDATE_COLUMNS)))
    for j, (x, y, alternative) in enumerate(items):
        rows[j, 0], rows[j, 1], rows[j, 6] = x, y, float(alternative)
    # oracle: the tracker's own start gate, candidate by candidate
    expected = [
        j
        for j, (x, y, alternative) in enumerate(items)
        if 0.0 < x <= gate.start_range_max_m and abs(y) <= gate.start_lateral_m and not alternative
    ]
    kept = start_gate_kernel(rows, gate.start_range_max_m, gate.start_lateral_m)
    assert kept.tolist() == expected
