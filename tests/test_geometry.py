"""Geometry kernels against independent oracles (shapely, brute force, closed forms)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, MultiPoint, Point, Polygon

from platoon_sumo.geometry import (
    centre_to_front_bumper,
    footprints_from_front_bumper,
    front_bumper_to_centre,
    overlapping_pairs,
    penetration_depths,
    rectangle_corners,
    rectangles_crossing_segments,
    rectangles_overlap,
    sumo_angle_deg_to_yaw,
    wrap_angle,
    yaw_to_sumo_angle_deg,
)
from platoon_sumo.kernels.rectangles import overlapping_pairs_kernel
from platoon_sumo.kernels.sideways import advanced, landing_conflicts, sideways_conflicts

SETTINGS = settings(deadline=None, max_examples=200)

coord = st.floats(-6.0, 6.0, allow_nan=False)
yaw = st.floats(-4.0 * math.pi, 4.0 * math.pi, allow_nan=False)
size = st.floats(0.2, 6.0, allow_nan=False)
rectangle = st.tuples(coord, coord, yaw, size, size)


def polygon(rect: tuple[float, ...]) -> Polygon:
    return Polygon(rectangle_corners(np.array(rect))[0])


# ---------------------------------------------------------------- angles


def test_wrap_angle_known_values_and_half_open_interval() -> None:
    assert wrap_angle(0.0) == 0.0
    assert wrap_angle(math.pi) == pytest.approx(-math.pi)
    assert wrap_angle(-math.pi) == pytest.approx(-math.pi)
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_angle(-1e-300) == -1e-300
    assert isinstance(wrap_angle(1.0), float)
    values = wrap_angle(np.linspace(-50, 50, 10_001))
    assert values.shape == (10_001,)
    assert np.all(values >= -math.pi) and np.all(values < math.pi)
    # Tiny negative offsets from -pi used to round up to +pi.
    assert wrap_angle(np.nextafter(-math.pi, -4.0)) < math.pi


@given(st.floats(-1e4, 1e4, allow_nan=False))
@SETTINGS
def test_wrap_angle_preserves_direction(a: float) -> None:
    w = wrap_angle(a)
    assert -math.pi <= w < math.pi
    assert math.cos(w) == pytest.approx(math.cos(a), abs=1e-9)
    assert math.sin(w) == pytest.approx(math.sin(a), abs=1e-9)


@pytest.mark.parametrize(
    ("yaw_rad", "sumo_deg"),
    [
        (0.0, 90.0),  # east
        (math.pi / 2, 0.0),  # north
        (-math.pi, 270.0),  # west
        (-math.pi / 2, 180.0),  # south
        (math.pi / 4, 45.0),  # north-east
    ],
)
def test_sumo_angle_known_values(yaw_rad: float, sumo_deg: float) -> None:
    assert yaw_to_sumo_angle_deg(yaw_rad) == pytest.approx(sumo_deg, abs=1e-12)
    assert sumo_angle_deg_to_yaw(sumo_deg) == pytest.approx(yaw_rad, abs=1e-12)


@given(yaw)
@SETTINGS
def test_sumo_angle_round_trip(y: float) -> None:
    deg = yaw_to_sumo_angle_deg(y)
    assert 0.0 <= deg < 360.0
    # Compare as directions: -pi and pi (just below) are the same heading.
    assert abs(wrap_angle(sumo_angle_deg_to_yaw(deg) - y)) < 1e-9


def test_sumo_angle_vectorised() -> None:
    yaws = np.array([0.0, math.pi / 2, -math.pi / 2])
    np.testing.assert_allclose(yaw_to_sumo_angle_deg(yaws), [90.0, 0.0, 180.0], atol=1e-12)
    np.testing.assert_allclose(sumo_angle_deg_to_yaw([90.0, 0.0, 180.0]), yaws, atol=1e-12)


# ---------------------------------------------------------------- footprints


def test_front_bumper_centre_round_trip_broadcasts() -> None:
    x, y, heading = np.array([0.0, 10.0]), np.array([0.0, -5.0]), np.array([0.0, math.pi / 2])
    cx, cy = front_bumper_to_centre(x, y, heading, 4.0)
    np.testing.assert_allclose(cx, [-2.0, 10.0], atol=1e-12)
    np.testing.assert_allclose(cy, [0.0, -7.0], atol=1e-12)
    bx, by = centre_to_front_bumper(cx, cy, heading, 4.0)
    np.testing.assert_allclose(bx, x, atol=1e-12)
    np.testing.assert_allclose(by, y, atol=1e-12)


def test_footprints_from_front_bumper() -> None:
    rects = footprints_from_front_bumper([5.0, 0.0], [0.0, 3.0], [0.0, math.pi], 4.0, [1.8, 2.0])
    assert rects.shape == (2, 5) and rects.dtype == np.float64
    np.testing.assert_allclose(rects[0], [3.0, 0.0, 0.0, 4.0, 1.8], atol=1e-12)
    np.testing.assert_allclose(rects[1], [2.0, 3.0, math.pi, 4.0, 2.0], atol=1e-12)
    assert footprints_from_front_bumper(1.0, 2.0, 0.0, 4.0, 2.0).shape == (1, 5)


def test_rectangle_corners_axis_aligned_ccw() -> None:
    corners = rectangle_corners(np.array([[1.0, 2.0, 0.0, 4.0, 2.0]]))
    np.testing.assert_allclose(corners[0], [[3, 1], [3, 3], [-1, 3], [-1, 1]], atol=1e-12)


def test_rectangle_corners_rotated_quarter_turn() -> None:
    corners = rectangle_corners(np.array([0.0, 0.0, math.pi / 2, 4.0, 2.0]))
    # Length now along +y: front-right corner is (+1, +2).
    np.testing.assert_allclose(corners[0], [[1, 2], [-1, 2], [-1, -2], [1, -2]], atol=1e-12)


@given(rectangle)
@SETTINGS
def test_rectangle_corners_match_shape(rect: tuple[float, ...]) -> None:
    poly = polygon(rect)
    assert poly.exterior.is_ccw
    assert poly.area == pytest.approx(rect[3] * rect[4], rel=1e-9)
    assert poly.centroid.x == pytest.approx(rect[0], abs=1e-9)
    assert poly.centroid.y == pytest.approx(rect[1], abs=1e-9)


def test_bad_rectangle_shape_is_rejected() -> None:
    with pytest.raises(ValueError, match=r"\(N, 5\)"):
        rectangle_corners(np.zeros((3, 4)))


# ---------------------------------------------------------------- overlap


@given(rectangle, rectangle)
@SETTINGS
def test_rectangles_overlap_matches_shapely(a: tuple[float, ...], b: tuple[float, ...]) -> None:
    pa, pb = polygon(a), polygon(b)
    area = pa.intersection(pb).area
    # Skip grazing pairs (tiny area, or touching at distance ~0): the oracle is ambiguous there.
    assume(area > 1e-9 or pa.distance(pb) > 1e-9)
    assert rectangles_overlap(np.array([a]), np.array([b]))[0] == (area > 1e-9)
    assert rectangles_overlap(np.array([b]), np.array([a]))[0] == (area > 1e-9)


@given(rectangle, rectangle, st.floats(0.0, 1.5, allow_nan=False))
@SETTINGS
def test_tolerance_is_penetration_depth(
    a: tuple[float, ...], b: tuple[float, ...], tolerance_m: float
) -> None:
    """Oracle: depth = distance from the origin to the boundary of the Minkowski difference."""
    ca, cb = rectangle_corners(np.array([a, b]))
    difference = MultiPoint((ca[:, None, :] - cb[None, :, :]).reshape(-1, 2)).convex_hull
    origin = Point(0.0, 0.0)
    depth = difference.exterior.distance(origin) if difference.contains(origin) else 0.0
    assume(abs(depth - tolerance_m) > 1e-9)
    got = rectangles_overlap(np.array([a]), np.array([b]), tolerance_m=tolerance_m)[0]
    assert got == (depth > tolerance_m)
    if depth > 1e-9:
        assert penetration_depths(np.array(a), np.array(b))[0] == pytest.approx(depth, abs=1e-9)


def test_touching_is_not_a_collision() -> None:
    a = np.array([[0.0, 0.0, 0.0, 2.0, 2.0]])
    b = np.array([[2.0, 0.0, 0.0, 2.0, 2.0]])  # shares an edge
    c = np.array([[2.0, 2.0, 0.0, 2.0, 2.0]])  # shares a corner
    assert not rectangles_overlap(a, b)[0]
    assert not rectangles_overlap(a, c)[0]
    nudged = b.copy()
    nudged[0, 0] -= 0.1  # 10 cm of penetration
    assert rectangles_overlap(a, nudged)[0]
    assert rectangles_overlap(a, nudged, tolerance_m=0.05)[0]
    assert not rectangles_overlap(a, nudged, tolerance_m=0.2)[0]


def test_rectangles_overlap_is_vectorised_and_broadcasts() -> None:
    a = np.array([[0.0, 0.0, 0.0, 4.0, 2.0]])
    b = np.array([[3.0, 0.0, 0.3, 4.0, 2.0], [10.0, 0.0, 0.0, 4.0, 2.0], [0.0, 1.5, 1.0, 4, 2]])
    np.testing.assert_array_equal(rectangles_overlap(a, b), [True, False, True])
    with pytest.raises(ValueError, match="tolerance_m"):
        rectangles_overlap(a, b, tolerance_m=-1.0)


# ---------------------------------------------------------------- overlapping pairs


def brute_force_pairs(rects: np.ndarray, subjects: np.ndarray, tol: float) -> np.ndarray:
    """Every subject against every other rectangle, no pruning."""
    n = len(rects)
    s = np.repeat(np.flatnonzero(subjects), n)
    o = np.tile(np.arange(n), int(subjects.sum()))
    s, o = s[s != o], o[s != o]
    pairs = np.unique(np.column_stack([np.minimum(s, o), np.maximum(s, o)]), axis=0)
    pairs = pairs.reshape(-1, 2).astype(np.int64)
    return pairs[rectangles_overlap(rects[pairs[:, 0]], rects[pairs[:, 1]], tol)]


@given(
    st.lists(rectangle, min_size=0, max_size=40),
    st.data(),
    st.sampled_from([0.0, 0.3]),
    st.floats(0.3, 3.0),
)
@SETTINGS
def test_overlapping_pairs_matches_brute_force(
    rects_list: list[tuple[float, ...]], data: st.DataObject, tol: float, spread: float
) -> None:
    rects = np.array(rects_list, dtype=np.float64).reshape(-1, 5)
    rects[:, :2] *= spread  # from crowded to sparse
    mask = np.array(
        data.draw(st.lists(st.booleans(), min_size=len(rects), max_size=len(rects))), dtype=bool
    )
    expected = brute_force_pairs(rects, mask, tol)
    got = overlapping_pairs(rects, mask, tol)
    assert got.dtype == np.int64 and got.shape[1] == 2
    np.testing.assert_array_equal(got, expected)
    # Index arrays (unsorted, with duplicates) mean the same as masks.
    idx = np.flatnonzero(mask)[::-1]
    np.testing.assert_array_equal(overlapping_pairs(rects, np.concatenate([idx, idx]), tol), got)
    # the loop's compiled sweep (sorted unique subject rows) finds the same pairs
    kernel = overlapping_pairs_kernel(rects, np.flatnonzero(mask), tol)
    assert kernel.dtype == np.int64 and kernel.shape == (len(expected), 2)
    np.testing.assert_array_equal(kernel, expected)


def test_overlapping_pairs_sorted_and_subject_rules() -> None:
    rects = np.array(
        [
            [0.0, 0.0, 0.0, 4.0, 2.0],  # 0 overlaps 1
            [3.0, 0.0, 0.0, 4.0, 2.0],  # 1 overlaps 0 and 2
            [6.0, 0.5, 0.0, 4.0, 2.0],  # 2
            [50.0, 50.0, 0.0, 4.0, 2.0],  # 3 alone
        ]
    )
    np.testing.assert_array_equal(overlapping_pairs(rects, [1]), [[0, 1], [1, 2]])
    np.testing.assert_array_equal(overlapping_pairs(rects, [0]), [[0, 1]])
    np.testing.assert_array_equal(overlapping_pairs(rects, [3]), np.empty((0, 2)))
    np.testing.assert_array_equal(
        overlapping_pairs(rects, np.ones(4, dtype=bool)), [[0, 1], [1, 2]]
    )
    assert overlapping_pairs(rects, np.zeros(4, dtype=bool)).shape == (0, 2)
    assert overlapping_pairs(np.empty((0, 5)), []).shape == (0, 2)


def test_overlapping_pairs_rejects_bad_subjects() -> None:
    rects = np.zeros((3, 5))
    with pytest.raises(ValueError, match="subject"):
        overlapping_pairs(rects, [3])
    with pytest.raises(ValueError, match="subject"):
        overlapping_pairs(rects, np.ones(2, dtype=bool))


def test_overlapping_pairs_far_coordinates() -> None:
    """UTM-sized coordinates and one long truck: the grid must stay exact."""
    base = np.array([[5.0e5, 4.0e6, 0.0, 4.0, 2.0], [5.0e5 + 3.0, 4.0e6, 0.2, 18.0, 2.5]])
    rects = np.vstack([base, [[5.0e5 + 1e4, 4.0e6, 0.0, 4.0, 2.0]]])
    np.testing.assert_array_equal(overlapping_pairs(rects, [0]), [[0, 1]])


def test_overlapping_pairs_city_scale_is_fast_and_exact() -> None:
    """3,000 vehicles on a straight north-south road (worst case for an x sweep)."""
    rng = np.random.default_rng(7)
    n = 3_000
    rects = np.column_stack(
        [
            rng.normal(0.0, 4.0, n),
            rng.uniform(0.0, 9_000.0, n),
            rng.normal(math.pi / 2, 0.1, n),
            rng.uniform(3.5, 5.0, n),
            rng.uniform(1.6, 2.0, n),
        ]
    )
    subjects = rng.choice(n, 100, replace=False)
    mask = np.zeros(n, dtype=bool)
    mask[subjects] = True
    start = time.perf_counter()
    got = overlapping_pairs(rects, subjects)
    elapsed_s = time.perf_counter() - start
    np.testing.assert_array_equal(got, brute_force_pairs(rects, mask, 0.0))
    assert len(got) > 0
    assert elapsed_s < 0.5


# ---------------------------------------------------------------- rectangles vs segments


@settings(max_examples=300, deadline=None)
@given(
    rect=st.tuples(
        st.floats(-5, 5), st.floats(-5, 5), st.floats(-4, 4), st.floats(0.3, 5), st.floats(0.2, 3)
    ),
    seg=st.tuples(st.floats(-9, 9), st.floats(-9, 9), st.floats(-9, 9), st.floats(-9, 9)),
)
def test_rectangles_crossing_segments_matches_shapely(rect, seg):
    corners = rectangle_corners(np.array([rect]))[0]
    poly = Polygon(corners)
    line = LineString([seg[:2], seg[2:]])
    shared = poly.intersection(line)
    inner = shared.length
    if 1e-10 < inner < 1e-6:
        return  # grazing or a near-point segment: below what either side resolves
    # crossing: some of the shared part off the outline (a segment running along a side
    # and on beyond the rectangle only touches it)
    expected = inner > 1e-9 and not poly.exterior.buffer(1e-9).contains(shared)
    pairs = rectangles_crossing_segments(np.array([rect]), np.array([seg]))
    assert (len(pairs) == 1) == expected


def test_rectangles_crossing_segments_known_cases():
    box = np.array([[0.0, 0.0, 0.0, 4.0, 2.0]])  # x in [-2, 2], y in [-1, 1]
    segments = np.array(
        [
            [-5.0, 0.0, 5.0, 0.0],  # straight through
            [0.0, 0.0, 0.5, 0.5],  # wholly inside
            [-5.0, 1.0, 5.0, 1.0],  # along the top side: touching only
            [3.0, -3.0, 3.0, 3.0],  # outside
            [2.0, 0.0, 4.0, 0.0],  # touching the front side at one point
        ]
    )
    pairs = rectangles_crossing_segments(box, segments)
    assert pairs.tolist() == [[0, 0], [0, 1]]


# ---------------------------------------------------------------- sideways moves
# (platoon_sumo.kernels.sideways, the check of sublane actuation)

#: A car at the origin facing east (front bumper at x 2.25) and its neighbours.
OWN = (0.0, 0.0, 0.0, 4.5, 1.8)


def conflicts(others, shift, speed=0.0, other_speed=0.0, margin=0.2):
    rects = np.array([OWN, *others])
    speeds = np.array([speed] + [other_speed] * len(others))
    turning = np.zeros(len(rects))
    return bool(
        sideways_conflicts(rects, speeds, turning, np.array([0]), np.array([shift]), 0.5, margin)[0]
    )


def test_a_move_towards_a_car_beside_conflicts_and_one_away_does_not():
    beside_left = (0.5, 2.5, 0.0, 4.5, 1.8)  # 0.7 m clear of our left side
    assert conflicts([beside_left], shift=0.6)
    assert not conflicts([beside_left], shift=0.4)  # stays clear with 0.2 m margin
    assert not conflicts([beside_left], shift=-0.6)


def test_driving_on_towards_the_car_ahead_is_no_sideways_conflict():
    """A car ahead in the lane is closer after the horizon; a small steering correction
    changes nothing about that."""
    ahead = (6.5, 0.0, 0.0, 4.5, 1.8)  # 2 m gap, we close it at 8 m/s
    assert not conflicts([ahead], shift=0.1, speed=8.0)
    assert not conflicts([ahead], shift=-0.1, speed=8.0)


def test_steering_into_a_car_ahead_in_the_next_lane_conflicts():
    """Where the highway follower steered into the car ahead-right (`highway`, 2026-11-26)."""
    ahead_right = (5.0, -2.3, 0.0, 5.0, 1.8)
    assert conflicts([ahead_right], shift=-0.5, speed=4.0, other_speed=3.0)
    assert not conflicts([ahead_right], shift=-0.5, speed=0.0, other_speed=3.0)  # it leaves


def test_a_car_passing_beside_at_speed_conflicts_while_it_is_level():
    """Found on a race circuit: a SUMO car overtaking at 19 m/s 0.3 m beside a platoon
    car at 2.6 m/s drifting towards it was level with it for two steps and 7 m past it
    at the horizon's end, where alone the move was checked."""
    passing = (-2.0, 2.1, 0.0, 4.5, 1.8)  # beside-left, 0.3 m clear, closing up at 19 m/s
    rects = np.array([OWN, passing])
    speeds, own, shift = np.array([2.6, 19.0]), np.array([0]), np.array([0.5])
    args = (rects, speeds, np.zeros(2), own)
    assert sideways_conflicts(*args, shift, 0.5, 0.2, 0.1)[0]
    assert sideways_conflicts(*args, shift, 0.5, 0.2, 0.15)[0]  # 0.15, 0.3, ...
    assert not sideways_conflicts(*args, shift, 0.5, 0.2)[0]  # the end only
    assert not sideways_conflicts(*args, -shift, 0.5, 0.2, 0.1)[0]  # away from it


def test_a_car_overtaking_on_a_curve_is_predicted_along_the_curve():
    """Found on a race circuit (seed 44, 471.9 s): a platoon car creeping at 0.7 m/s
    steered back towards its path on a right-hand curve of about 50 m while a SUMO car
    overtook it at 24 m/s inside the same wide lane. Along its yaw the overtaking car
    stays clear of the move; along the curve it comes 0.6 m nearer while level."""
    passing = (-8.0, 2.6, 0.0, 4.5, 1.8)  # behind-left, 0.8 m clear sideways
    rects = np.array([OWN, passing])
    speeds, own, shift = np.array([0.7, 24.0]), np.array([0]), np.array([0.3])
    curve = np.array([0.0, -24.0 / 50.0])  # it turns right, towards us

    def blocked(turning: np.ndarray, towards: np.ndarray) -> bool:
        return bool(sideways_conflicts(rects, speeds, turning, own, towards, 0.5, 0.2, 0.1)[0])

    assert blocked(curve, shift)
    assert not blocked(np.zeros(2), shift)  # predicted straight on it stays clear
    assert not blocked(-curve, shift)  # turning away from us
    assert not blocked(curve, -shift)  # moving away from it


@SETTINGS
@given(
    x=st.floats(-50.0, 50.0), y=st.floats(-50.0, 50.0), yaw=st.floats(-math.pi, math.pi),
    speed=st.floats(0.0, 40.0), rate=st.floats(-2.0, 2.0), time=st.floats(0.0, 2.0),
)  # fmt: skip
def test_advanced_drives_on_at_constant_speed_and_yaw_rate(x, y, yaw, speed, rate, time):
    """Oracle: the same motion integrated in 4,000 small steps (midpoint rule).

    The midpoint rule's chord error is speed * time * (rate * step)^2 / 24, at most
    3.4 µm here, so positions are compared to 10 µm.
    """
    steps = 4000
    dt = time / steps
    px, py, heading = x, y, yaw
    for _ in range(steps):
        mid = heading + 0.5 * rate * dt
        px, py = px + math.cos(mid) * speed * dt, py + math.sin(mid) * speed * dt
        heading += rate * dt
    got = advanced(x, y, yaw, speed, rate, time)
    assert got[0] == pytest.approx(px, abs=1e-5)
    assert got[1] == pytest.approx(py, abs=1e-5)
    assert got[2] == pytest.approx(heading, abs=1e-9)


def test_vehicles_outside_the_world_or_not_moving_sideways_never_conflict():
    rects = np.array([OWN, (0.0, 1.5, 0.0, 4.5, 1.8)])
    still, subjects = np.zeros(2), np.array([-1, 0])
    out = sideways_conflicts(rects, still, still, subjects, np.array([1.0, 0.0]), 0.5, 0.2)
    assert not out.any()


@given(st.lists(rectangle, min_size=1, max_size=4), st.floats(-2.0, 2.0, allow_nan=False),
       st.floats(0.0, 0.5, allow_nan=False))  # fmt: skip
@SETTINGS
def test_sideways_conflicts_against_shapely(others, shift, margin):
    """Oracle: shapely polygons of the enlarged car before and after the shift (nothing
    moves on: speeds 0). No overlap after the shift: no conflict. A car the unshifted
    one does not touch and the shifted one overlaps by more than 2 mm (its polygon,
    shrunk by 2 mm, still meets it): a conflict."""
    assume(shift != 0.0)
    rects = np.array([OWN, *others])
    still = np.zeros(len(rects))
    hit = sideways_conflicts(rects, still, still, np.array([0]), np.array([shift]),
                             0.5, margin)[0]  # fmt: skip
    length, width = OWN[3] + 2 * margin, OWN[4] + 2 * margin
    before = polygon((OWN[0], OWN[1], OWN[2], length, width))
    after = polygon((OWN[0], OWN[1] + shift, OWN[2], length, width))
    others_ = [polygon(o) for o in others]
    if all(after.intersection(o).area <= 1e-9 for o in others_):
        assert not hit
    if any(before.distance(o) > 0.0 and after.buffer(-0.002).intersects(o) for o in others_):
        assert hit


def moved(rect: tuple[float, ...], speed_mps: float, time_s: float, grow_m: float = 0.0):
    """A rectangle driven on along its yaw for `time_s`, `grow_m` larger on every side."""
    x, y, a, length, width = rect
    dx, dy = math.cos(a) * speed_mps * time_s, math.sin(a) * speed_mps * time_s
    return (x + dx, y + dy, a, length + 2 * grow_m, width + 2 * grow_m)


@SETTINGS
@given(
    others=st.lists(
        st.tuples(rectangle, st.floats(0.0, 15.0, allow_nan=False)), min_size=1, max_size=4
    ),
    landing=rectangle,
    landing_speed=st.floats(0.0, 15.0, allow_nan=False),
)
def test_landing_conflicts_as_shapely_sees_the_rectangles_drive_on(others, landing, landing_speed):
    """A landing conflicts when, `margin` larger, it overlaps another rectangle now or at
    any step within the horizon, both driving on along their yaws (shapely on the moved
    polygons); row 0 is the landing car's own and never counts. Contacts of zero area
    may go either way."""
    rects = np.array([landing, *(r for r, _ in others)])
    speeds = np.array([landing_speed, *(v for _, v in others)])
    horizon, margin, step = 1.0, 0.2, 0.25
    got = landing_conflicts(
        rects, speeds, np.zeros(len(rects)), np.array([0]), np.array([landing]),
        np.array([landing_speed]),
        horizon, margin, step,
    )[0]  # fmt: skip
    areas, gaps = [], []
    for t in np.arange(0.0, horizon + 1e-9, step):
        mine = polygon(moved(landing, landing_speed, t, margin))
        for r, v in others:
            other = polygon(moved(r, v, t))
            areas.append(mine.intersection(other).area)
            gaps.append(mine.distance(other))
    if max(areas) > 1e-6:
        assert got
    elif min(gaps) > 1e-6:
        assert not got


def test_a_landing_in_reach_of_a_car_coming_up_behind_conflicts():
    """Put down 3 m ahead of a car closing at 6 m/s more: in its way within a second."""
    landing = (0.0, 0.0, 0.0, 4.5, 1.8)
    behind = (-7.5, 0.0, 0.0, 4.5, 1.8)  # 3 m gap
    rects = np.array([landing, behind])
    args = (np.array([0]), np.array([landing]))

    def check(own_mps: float, behind_mps: float) -> bool:
        speeds = np.array([own_mps, behind_mps])
        own = np.array([own_mps])
        return bool(landing_conflicts(rects, speeds, np.zeros(2), *args, own, 1.0, 0.2, 0.1)[0])

    assert check(2.0, 8.0)
    assert not check(2.0, 2.0)
    assert not check(8.0, 2.0)  # it drives away from it
