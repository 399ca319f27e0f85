"""Per-step metric formulas on hand-computed values (docs/metrics.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from platoon_sumo.metrics.kernels import (
    Trails,
    desired_gap_m,
    jerk_mps3,
    l2_gain,
    spacing_error_m,
    time_gap_s,
    time_to_collision_s,
)

NAN = math.nan


def _cells(values: np.ndarray) -> list[float | None]:
    """Table cells: None where the value is NaN (no value)."""
    return [None if math.isnan(v) else v for v in values.tolist()]


def test_spacing_error_is_gap_minus_desired_gap():
    error = spacing_error_m(np.array([12.0, NAN, 10.0]), np.array([10.5, 10.0, NAN]))
    assert _cells(error) == [pytest.approx(1.5), None, None]


def test_desired_gap_is_the_policys_gap_at_the_speed_never_below_standstill():
    desired = desired_gap_m(np.array([2.0, 2.0, 5.0]), np.array([1.5, 1.5, 0.0]),
                            np.array([10.0, -1.0, 30.0]))  # fmt: skip
    assert desired.tolist() == [17.0, 2.0, 5.0]


def test_time_gap_is_gap_over_own_speed_and_undefined_at_standstill():
    gaps = time_gap_s(np.array([20.0, 20.0, NAN]), np.array([10.0, 0.0, 10.0]))
    assert _cells(gaps) == [pytest.approx(2.0), None, None]


def test_time_to_collision_only_while_closing_in():
    ttc = time_to_collision_s(
        np.array([10.0, 10.0, 10.0, 10.0, -1.0]),
        np.array([15.0, 10.0, 8.0, 8.0, 12.0]),
        np.array([10.0, 10.0, 10.0, NAN, 10.0]),
    )  # closing; same speed; opening; no predecessor; overlapping while closing
    assert _cells(ttc) == [pytest.approx(2.0), None, None, None, 0.0]


def test_jerk_is_the_change_of_acceleration_over_the_step():
    jerk = jerk_mps3(np.array([1.0, 1.0]), np.array([0.5, NAN]), 0.1)
    assert _cells(jerk) == [pytest.approx(5.0), None]
    assert _cells(jerk_mps3(np.array([1.0]), np.array([0.5]), 0.0)) == [None]


def _scalar_metrics(gap, speed, pred_speed, standstill, time_gap, accel, before, dt):
    """The formulas of docs/metrics.md one vehicle at a time, None for no value."""
    desired = None if standstill is None else standstill + time_gap * max(speed, 0.0)
    error = None if gap is None or desired is None else gap - desired
    headway = None if gap is None or speed <= 0.01 else gap / speed
    closing = None if pred_speed is None else speed - pred_speed
    ttc = None if gap is None or closing is None or closing <= 1e-6 else max(gap, 0.0) / closing
    jerk = None if before is None or dt <= 0 else (accel - before) / dt
    return desired, error, headway, ttc, jerk


_maybe = st.one_of(st.none(), st.floats(-50, 50))


@given(
    st.lists(
        st.tuples(_maybe, st.floats(-1, 40), st.one_of(st.none(), st.floats(0, 40)),
                  st.one_of(st.none(), st.floats(0, 20)), st.floats(0, 3), st.floats(-9, 9),
                  st.one_of(st.none(), st.floats(-9, 9))),
        min_size=1, max_size=20,
    ),
    st.sampled_from([0.0, 0.05, 0.1]),
)  # fmt: skip
def test_the_array_formulas_are_the_scalar_ones_value_for_value(rows, dt):
    """Each vehicle's metrics over a step's arrays are, bit for bit, its own (an
    independent scalar oracle), and no value exactly where the oracle has none."""
    gap, speed, pred, standstill, tg, accel, before = (
        np.array(col, dtype=np.float64) for col in zip(*rows, strict=True)
    )
    desired = desired_gap_m(standstill, np.where(np.isnan(standstill), NAN, tg), speed)
    got = zip(
        _cells(desired), _cells(spacing_error_m(gap, desired)), _cells(time_gap_s(gap, speed)),
        _cells(time_to_collision_s(gap, speed, pred)), _cells(jerk_mps3(accel, before, dt)),
        strict=True,
    )  # fmt: skip
    for row, values in zip(rows, got, strict=True):
        g, v, p, s0, t, a, b = row
        assert values == _scalar_metrics(g, v, p, s0, t, a, b, dt)


def test_l2_gain_of_sampled_signals():
    # out = 0.5 * in, sample by sample: gain 0.5
    inp = [1.0, -2.0, 3.0]
    out = [0.5 * x for x in inp]
    assert l2_gain(sum(x * x for x in out), sum(x * x for x in inp)) == pytest.approx(0.5)
    assert l2_gain(1.0, 0.0) is None


class _One:
    """One vehicle's trail in `Trails`, for the single-trail cases."""

    def __init__(self, spacing_m: float, max_points: int = 5000):
        self.trails, self.spacing_m = Trails(max_points), spacing_m

    def append(self, x: float, y: float) -> None:
        self.trails.append(["a"], np.array([x]), np.array([y]), np.array([self.spacing_m]))

    def deviation(self, x: float, y: float, prune: bool = True) -> float | None:
        d = self.trails.deviation(["a"], np.array([x]), np.array([y]), prune)[0]
        return None if math.isnan(d) else float(d)

    def __len__(self) -> int:
        return len(self.trails.points("a")) if "a" in self.trails else 0


def test_trail_deviation_beside_behind_and_past_the_path():
    trail = _One(spacing_m=1.0)
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
    trail = _One(spacing_m=0.5, max_points=100)
    for k in range(10_000):
        trail.append(0.5 * k, 0.0)
    assert len(trail) == 100
    assert trail.deviation(4990.2, 1.0) == pytest.approx(1.0)
    assert trail.trails._buf.shape[1] <= 101  # rows a trail, whatever the run's length


def test_a_vehicle_without_a_trail_has_no_deviation():
    trails = Trails()
    trails.append(["a"], np.zeros(1), np.zeros(1), np.zeros(1))
    assert np.isnan(trails.deviation(["b", "a"], np.zeros(2), np.ones(2))).all()


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
    trail = _One(spacing_m=0.0, max_points=1000)
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


@given(
    st.integers(1, 30),
    st.lists(st.tuples(st.integers(0, 4), st.integers(0, 5)), max_size=300),
)
def test_trails_keep_each_vehicles_newest_points_in_order(max_points, moves):
    """Many vehicles' appends, prunes, compactions, growth and forgetting keep, for
    each vehicle, exactly its newest points, oldest first, as a list of its own would
    (the oracle); a forgotten vehicle starts again from nothing."""
    trails = Trails(max_points)
    kept: dict[str, list[tuple[float, float]]] = {}
    for k, (move, who) in enumerate(moves):
        vid = f"v{who}"
        if move == 0 and len(kept.get(vid, [])) > 1:
            trails.keep_last(1, [vid])
            kept[vid] = kept[vid][-1:]
        elif move == 1 and vid in kept:
            trails.forget([vid])
            del kept[vid]
        else:  # a step of every vehicle in the step: appended in one call
            ids = [vid, f"w{who}"]
            trails.append(ids, np.array([float(k), 0.5 * k]), np.zeros(2), np.zeros(2))
            for i, x in zip(ids, (float(k), 0.5 * k), strict=True):
                kept[i] = [*kept.get(i, []), (x, 0.0)][-max_points:]
        assert sorted(trails.ids()) == sorted(kept)
        for i, points in kept.items():
            assert trails.points(i).tolist() == [list(p) for p in points]
