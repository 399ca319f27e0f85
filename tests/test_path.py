"""RoutePath: resampling, look-ups and projection against closed forms."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.path import LaneChange, RoutePath
from tests.control import reference_path as ref


def circle_path(radius_m: float, spacing_m: float = 0.05) -> RoutePath:
    """Counter-clockwise circle around the origin starting at (R, 0), 3/4 of a turn."""
    t = np.linspace(0.0, 1.5 * math.pi, 2000)
    pts = np.column_stack([radius_m * np.cos(t), radius_m * np.sin(t)])
    return RoutePath.from_pieces([pts], ["c_0"], [10.0], [3.2], spacing_m)


def test_straight_pieces_join_into_one_path_with_lane_ownership():
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    b = np.array([[10.0, 0.0], [10.0, 5.0]])
    path = RoutePath.from_pieces([a, b], ["a_0", ":j_0_0"], [13.9, 5.0], [3.2, 3.0], 0.5)
    assert math.isclose(path.length_m, 15.0, abs_tol=1e-9)
    assert path.point_at(12.0) == (10.0, 2.0)
    assert path.lane_at(3.0) == "a_0" and path.lane_at(12.0) == ":j_0_0"
    assert math.isclose(path.heading_at(4.0), 0.0) and math.isclose(
        path.heading_at(13.0), math.pi / 2
    )
    i = int(12.0 / path.spacing_m)
    assert path.speed_limit_mps[i] == 5.0 and path.lane_width_m[i] == 3.0


@settings(max_examples=200, deadline=None)
@given(
    angle=st.floats(0.05, 1.45 * math.pi),
    offset=st.floats(-1.5, 1.5),
)
def test_projection_on_a_circle_matches_polar_geometry(angle, offset):
    radius = 20.0
    path = circle_path(radius)
    r = radius - offset  # left of a counter-clockwise circle is towards its centre
    point = path.project(r * math.cos(angle), r * math.sin(angle))
    # Chord error of the polyline is at most R (1 - cos(dtheta / 2)) ~ 6e-6 m here.
    assert math.isclose(point.lateral_offset_m, offset, abs_tol=1e-4)
    # Off the centre-line, the foot point on a chord shifts by up to spacing * |offset| / R.
    assert math.isclose(point.s_m, radius * angle, abs_tol=0.05 * abs(offset) / radius + 1e-4)


def test_projection_with_hint_does_not_jump_to_a_later_pass():
    # An out-and-back route: both passes lie 0.4 m apart.
    out = np.array([[0.0, 0.0], [50.0, 0.0]])
    turn = np.array([[50.0, 0.0], [50.0, 0.4]])
    back = np.array([[50.0, 0.4], [0.0, 0.4]])
    path = RoutePath.from_pieces([out, turn, back], ["o", "t", "b"], [1, 1, 1], [3, 3, 3], 0.25)
    near_return_lane = (10.0, 0.3)
    assert path.project(*near_return_lane).s_m > 50.0  # globally nearest: the way back
    assert path.project(*near_return_lane, s_hint_m=9.0, window_m=5.0).s_m < 15.0


def test_curvature_of_a_circle_is_one_over_radius():
    path = circle_path(25.0)
    kappa = path.curvature_1pm(smoothing_m=1.0)
    inner = kappa[50:-50]
    assert np.allclose(inner, 1 / 25.0, rtol=5e-3)


def test_lane_beside_counts_lanes_by_offset_on_the_same_edge():
    # edge a (lane 1) for 100 m, a junction lane for 10 m, edge b (lane 0) for 100 m;
    # the route changes from lane 1 to lane 0 of b between 150 and 180 m
    a = np.array([[0.0, 0.0], [100.0, 0.0]])
    junction = np.array([[100.0, 0.0], [110.0, 0.0]])
    b = np.array([[110.0, 0.0], [210.0, 0.0]])
    change = LaneChange(150.0, 180.0, ("b_0",))
    path = RoutePath.from_pieces(
        [a, junction, b], ["a_1", ":j_0_0", "b_0"], [13.9] * 3, [3.2] * 3, 0.5, [change]
    )
    assert path.lane_beside(50.0, 0.0) == ("a", 1)
    assert path.lane_beside(50.0, 3.1) == ("a", 2)  # one lane to the left
    assert path.lane_beside(50.0, -3.3) == ("a", 0)
    assert path.lane_beside(50.0, 1.0) == ("a", 1)  # still the same lane
    assert path.lane_beside(105.0, 0.0) is None  # inside the junction
    assert path.lane_beside(160.0, 0.0) is None  # the path is between lanes
    assert path.lane_beside(200.0, 3.2) == ("b", 1)


# ----------------------------------------------------------------------------- fast look-ups


def lane_change_path() -> RoutePath:
    """Edge a (lane 1), a junction lane, edge b (lane 0) with a lane change, a left bend."""
    a = np.array([[0.0, 0.0], [100.0, 0.0]])
    junction = np.array([[100.0, 0.0], [107.0, 3.0], [110.0, 10.0]])
    t = np.linspace(0.0, 0.5 * math.pi, 60)
    b = np.column_stack([110.0 + 40.0 * (1.0 - np.cos(t)), 10.0 + 40.0 * np.sin(t)])
    change = LaneChange(140.0, 170.0, ("b_0",))
    return RoutePath.from_pieces(
        [a, junction, b], ["a_1", ":j_0_0", "b_0"], [13.9, 8.0, 13.9], [3.2, 3.0, 3.5], 0.5,
        [change],
    )  # fmt: skip


PATHS = {"circle": lambda: circle_path(20.0, spacing_m=0.3), "lanes": lane_change_path}


@settings(max_examples=300, deadline=None)
@given(
    name=st.sampled_from(sorted(PATHS)),
    x=st.floats(-30.0, 200.0),
    y=st.floats(-30.0, 60.0),
    hint=st.one_of(st.none(), st.floats(-20.0, 300.0)),
    window=st.floats(0.0, 60.0),
)
def test_projection_matches_the_numpy_reference(name, x, y, hint, window):
    """The compiled projection (window arithmetic, nearest segment, first of ties, sign)
    equals the numpy implementation it replaced."""
    path = PATHS[name]()
    got = path.project(x, y, hint, window)
    want = ref.project(path, x, y, hint, window)
    assert math.isclose(got.s_m, want.s_m, abs_tol=1e-9)
    assert math.isclose(got.lateral_offset_m, want.lateral_offset_m, abs_tol=1e-9)
    assert path.project_sl(x, y, hint, window) == (got.s_m, got.lateral_offset_m)


@settings(max_examples=300, deadline=None)
@given(
    name=st.sampled_from(sorted(PATHS)),
    s=st.floats(-20.0, 300.0),
    target_s=st.floats(-20.0, 300.0),
    offset=st.floats(-8.0, 8.0),
    target_offset=st.floats(-8.0, 8.0),
)
def test_scalar_lookups_match_the_numpy_reference(name, s, target_s, offset, target_offset):
    path = PATHS[name]()
    got, want = path.point_at(s), ref.point_at(path, s)
    assert math.isclose(got[0], want[0], abs_tol=1e-9)
    assert math.isclose(got[1], want[1], abs_tol=1e-9)
    assert math.isclose(path.heading_at(s), ref.heading_at(path, s), abs_tol=1e-12)
    assert path.lane_at(s) == ref.lane_at(path, s)
    assert path.lane_beside(s, offset) == ref.lane_beside(path, s, offset)
    assert path.lane_step(s, offset, target_s, target_offset) == ref.lane_step(
        path, s, offset, target_s, target_offset
    )
    assert path.same_lane(s, offset, target_s, target_offset) == ref.same_lane(
        path, s, offset, target_s, target_offset
    )
    assert path.length_m == ref.length_m(path)


@settings(max_examples=200, deadline=None)
@given(
    name=st.sampled_from(sorted(PATHS)),
    points=st.lists(st.tuples(st.floats(-30.0, 200.0), st.floats(-30.0, 60.0)), max_size=12),
    hint=st.floats(-20.0, 300.0),
    window=st.floats(0.0, 60.0),
)
def test_many_points_project_as_each_does_alone(name, points, hint, window):
    """``project_sl_many`` (one kernel call, one hint) gives each point's projection as
    the numpy reference finds it."""
    path = PATHS[name]()
    xy = np.array(points, dtype=np.float64).reshape(-1, 2)
    s, lateral = path.project_sl_many(xy[:, 0], xy[:, 1], hint, window)
    assert s.shape == lateral.shape == (len(points),)
    for (x, y), got_s, got_lateral in zip(points, s.tolist(), lateral.tolist(), strict=True):
        want = ref.project(path, x, y, hint, window)
        assert math.isclose(got_s, want.s_m, abs_tol=1e-9)
        assert math.isclose(got_lateral, want.lateral_offset_m, abs_tol=1e-9)
    for bad_hint, bad_window in ((math.nan, 10.0), (10.0, -1.0)):
        try:
            path.project_sl_many(xy[:, 0], xy[:, 1], bad_hint, bad_window)
        except ValueError:
            continue
        raise AssertionError(f"no error for hint {bad_hint}, window {bad_window}")


def test_projection_with_integer_arguments_and_bad_hints():
    path = lane_change_path()
    assert path.project(50, 1, 40, 20) == path.project(50.0, 1.0, 40.0, 20.0)
    for hint, window in ((math.nan, 10.0), (math.inf, 10.0), (10.0, -1.0), (10.0, math.inf)):
        try:
            path.project(50.0, 1.0, hint, window)
        except ValueError:
            continue
        raise AssertionError(f"no error for hint {hint}, window {window}")


def test_lanes_are_named_by_the_map_along_a_routes_lane_change():
    """A route's lane change blends lane 0's shape into lane 1's inside one edge and
    keeps lane 0's id (network.route_path). Lanes beside the path are still named by
    the map: before the change the path runs on lane 0, after it on lane 1, halfway
    between them in the middle; so a car on lane 1 before the change and one on the
    path after it are in the same lane."""
    x = np.linspace(0.0, 200.0, 401)
    u = np.clip((x - 50.0) / 100.0, 0.0, 1.0)
    y = 3.2 * u * u * (3 - 2 * u)  # smoothstep from lane 0 (y=0) to lane 1 (y=3.2)
    change = LaneChange(50.0, 150.0, ("e_1",))
    path = RoutePath.from_pieces([np.column_stack([x, y])], ["e_0"], [14.0], [3.2], 0.5, [change])
    before, middle, after = 20.0, path.project(100.0, 1.6).s_m, path.project(190.0, 3.2).s_m
    assert path.same_lane(before, 3.2, after, 0.0)  # lane 1 both
    assert path.same_lane(before, 0.0, after, -3.2)  # lane 0 both
    assert not path.same_lane(before, 0.0, after, 0.0)  # lane 0, lane 1
    assert path.same_lane(middle, 1.0, after, 0.0)  # half a lane up, plus 1 m: lane 1
    assert path.same_lane(middle, -1.0, before, 0.0)  # half a lane up, minus 1 m: lane 0
    assert not path.same_lane(before, float("nan"), after, 0.0)


def junction_path() -> RoutePath:
    """Road, junction, road, junction, road: 20 m pieces at 0.5 m spacing."""
    xs = [np.linspace(20 * k, 20 * (k + 1), 41) for k in range(5)]
    pieces = [np.column_stack([x, np.zeros(41)]) for x in xs]
    lanes = ["a_0", ":j_0_0", "b_0", ":k_0_0", "c_0"]
    return RoutePath.from_pieces(pieces, lanes, [13.9] * 5, [3.2] * 5, 0.5)


@settings(max_examples=300, deadline=None)
@given(
    st.floats(-30.0, 130.0, allow_nan=False),
    st.floats(-30.0, 130.0, allow_nan=False),
)
def test_junction_within_finds_any_point_on_an_internal_lane(from_s, to_s):
    # oracle: the points the stretch covers (one point of slack after it, as the
    # follower's guard has it), each read by its lane's id
    path = junction_path()
    n = len(path.lane_index)
    i0 = min(max(int(from_s // path.spacing_m), 0), n)
    i1 = min(max(int(to_s // path.spacing_m) + 2, 0), n)
    expected = any(path.lane_ids[int(path.lane_index[i])].startswith(":") for i in range(i0, i1))
    assert path.junction_within(from_s, to_s) is expected


def test_junction_within_on_the_road_and_in_the_junction():
    path = junction_path()
    assert not path.junction_within(2.0, 15.0)  # on the first road only
    assert path.junction_within(15.0, 25.0)  # into the first junction
    assert path.junction_within(25.0, 30.0)  # inside it
    assert not path.junction_within(45.0, 55.0)  # the second road
    assert not path.junction_within(50.0, 40.0)  # an empty stretch
