"""Per-step metric formulas on hand-computed values (docs/metrics.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from platoon_sumo.metrics.kernels import (
    PathTrail,
    jerk_mps3,
    l2_gain,
    spacing_error_m,
    time_gap_s,
    time_to_collision_s,
)


def test_spacing_error_is_gap_minus_desired_gap():
    assert spacing_error_m(12.0, 10.5) == pytest.approx(1.5)
    assert spacing_error_m(None, 10.0) is None
    assert spacing_error_m(10.0, None) is None


def test_time_gap_is_gap_over_own_speed_and_undefined_at_standstill():
    assert time_gap_s(20.0, 10.0) == pytest.approx(2.0)
    assert time_gap_s(20.0, 0.0) is None
    assert time_gap_s(None, 10.0) is None


def test_time_to_collision_only_while_closing_in():
    assert time_to_collision_s(10.0, 15.0, 10.0) == pytest.approx(2.0)
    assert time_to_collision_s(10.0, 10.0, 10.0) is None  # same speed
    assert time_to_collision_s(10.0, 8.0, 10.0) is None  # opening
    assert time_to_collision_s(10.0, 8.0, None) is None


def test_jerk_is_the_change_of_acceleration_over_the_step():
    assert jerk_mps3(1.0, 0.5, 0.1) == pytest.approx(5.0)
    assert jerk_mps3(1.0, None, 0.1) is None


def test_l2_gain_of_sampled_signals():
    # out = 0.5 * in, sample by sample: gain 0.5
    inp = [1.0, -2.0, 3.0]
    out = [0.5 * x for x in inp]
    assert l2_gain(sum(x * x for x in out), sum(x * x for x in inp)) == pytest.approx(0.5)
    assert l2_gain(1.0, 0.0) is None


def test_trail_deviation_beside_behind_and_past_the_path():
    trail = PathTrail(spacing_m=1.0)
    for x in range(11):  # the predecessor drove along y = 0 from x = 0 to 10
        trail.append(float(x), 0.0)
    trail.append(10.5, 0.0)  # closer than the spacing: not kept
    assert len(trail) == 11
    assert trail.deviation(-2.0, 0.3) is None  # behind its start
    assert trail.deviation(12.0, 0.3) is None  # past its end
    assert trail.deviation(3.5, -0.4, prune=False) == pytest.approx(0.4)
    # pruning drops the points before the nearest segment, not the segment itself
    assert trail.deviation(5.5, 0.2) == pytest.approx(0.2)
    assert len(trail) == 6
    assert trail.deviation(5.2, 0.1) == pytest.approx(0.1)


def test_trail_memory_is_bounded():
    trail = PathTrail(spacing_m=0.5, max_points=100)
    for k in range(10_000):
        trail.append(0.5 * k, 0.0)
    assert len(trail) == 100
    assert trail.deviation(4990.2, 1.0) == pytest.approx(1.0)
    assert math.isfinite(trail.spacing_m)


def _deviation_oracle(points: list[tuple[float, float]], x: float, y: float):
    """Brute force in numpy: nearest segment and distance, None outside the trail."""
    pts = np.asarray(points, dtype=np.float64)
    a, e = pts[:-1], np.diff(pts, axis=0)
    ee = (e * e).sum(axis=1)
    raw = np.divide(
        ((np.array([x, y]) - a) * e).sum(axis=1), ee, out=np.zeros(len(e)), where=ee > 0
    )
    t = np.clip(raw, 0.0, 1.0)
    d = np.hypot(a[:, 0] + t * e[:, 0] - x, a[:, 1] + t * e[:, 1] - y)
    j = int(np.argmin(d))
    if (j == 0 and raw[0] <= 1e-9) or (j == len(e) - 1 and raw[-1] >= 1.0 - 1e-9):
        return None
    return j, float(d[j])


coord = st.floats(-50.0, 50.0, allow_nan=False)


@given(
    points=st.lists(st.tuples(coord, coord), min_size=2, max_size=40),
    x=coord,
    y=coord,
)
def test_trail_deviation_matches_brute_force(points, x, y):
    trail = PathTrail(spacing_m=0.0, max_points=1000)
    for px, py in points:
        trail.append(px, py)
    expected = _deviation_oracle(points, x, y)
    before = len(trail)
    got = trail.deviation(x, y)
    if expected is None:
        assert got is None and len(trail) == before
    else:
        assert got == pytest.approx(expected[1], abs=1e-9)
        assert len(trail) == before - expected[0]  # the passed points are gone


@given(st.integers(1, 30), st.lists(st.integers(0, 3), max_size=300))
def test_trail_keeps_the_newest_points_in_order(max_points, moves):
    """Appends, prunes and compactions keep exactly the newest points, oldest first."""
    trail = PathTrail(spacing_m=0.0, max_points=max_points)
    kept: list[tuple[float, float]] = []
    for k, move in enumerate(moves):
        if move == 0 and len(kept) > 1:
            trail.keep_last(1)
            kept = kept[-1:]
        else:
            trail.append(float(k), 0.0)
            kept = [*kept, (float(k), 0.0)][-max_points:]
        assert len(trail) == len(kept)
    if len(kept) >= 2:
        assert trail.deviation(kept[0][0] + 0.5, 1.0, prune=False) == pytest.approx(1.0)
        assert trail.deviation(kept[-1][0] - 0.5, -2.0, prune=False) == pytest.approx(2.0)
