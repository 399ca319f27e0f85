"""The corridor kernel (platoon_sumo.kernels.corridor) against shapely: which rectangles
reach into a chain of slices along a polyline, and at which slice first."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon, box
from shapely.ops import unary_union

from platoon_sumo.geometry import rectangle_corners
from platoon_sumo.kernels.corridor import corridor_intrusions, empty_outputs
from platoon_sumo.loop.obstacles import (
    CROSSING_DECEL_MPS2,
    crosses_before_arrival,
    sidestep_clearing,
)
from platoon_sumo.path import RoutePath


def slice_polygon(a: np.ndarray, b: np.ndarray, half_width: float) -> Polygon:
    t = (b - a) / np.linalg.norm(b - a)
    n = np.array([-t[1], t[0]]) * half_width
    return Polygon([a - n, b - n, b + n, a + n])


def oracle(samples, sample_s, half_width, rects, self_index):
    """{rect: gap} by shapely: the first slice each rectangle's polygon overlaps."""
    found = {}
    polygons = [Polygon(c) for c in rectangle_corners(rects)]
    for k, rect in enumerate(polygons):
        if k == self_index:
            continue
        for i in range(len(samples) - 1):
            if slice_polygon(samples[i], samples[i + 1], half_width).intersection(rect).area > 1e-9:
                found[k] = sample_s[i]
                break
    return found


def kernel(path, half_width, rects, self_index, owners=None, body_m=0.0):
    """The kernel on one path, the corridor from its start to its end."""
    outputs = empty_outputs(64)
    member = np.array([[0, 0.0, 0.0, 1e9, path.spacing_m, 1, half_width, body_m]])
    owners = np.arange(len(rects)) if owners is None else np.asarray(owners)
    count = corridor_intrusions(
        path.xy_m, path.left_normals, np.array([0, len(path.xy_m)]), member,
        np.array([self_index]), rects, owners, *outputs,
    )  # fmt: skip
    _, rect, gap, _ = (a[:count] for a in outputs)
    return dict(zip(rect.tolist(), gap.tolist(), strict=True))


def arc(radius: float, length: float, step: float) -> tuple[RoutePath, np.ndarray, np.ndarray]:
    """A path along a circular arc (or a line), its points and their arc lengths."""
    s = np.arange(0.0, length, 0.05)
    if math.isinf(radius):
        xy = np.column_stack([s, np.zeros_like(s)])
    else:
        angle = s / radius
        xy = np.column_stack([radius * np.sin(angle), radius * (1 - np.cos(angle))])
    path = RoutePath.from_pieces([xy], ["e_0"], [10.0], [3.2], step)
    return path, path.xy_m, np.arange(len(path.xy_m)) * step


def test_a_corner_reaching_into_the_lane_is_found_at_its_distance():
    path, _, _ = arc(math.inf, 30.0, 0.5)
    # a car beside the lane, 12-16.5 m ahead, its side 0.3 m into the 2.2 m corridor
    rects = np.array([[-2.0, 0.0, 0.0, 4.5, 1.8], [14.25, 1.1 + 0.9 - 0.3, 0.0, 4.5, 1.8]])
    assert kernel(path, 1.1, rects, 0) == {1: 12.0}
    # rectangles belong to vehicles: vehicle 0's (here the second) are skipped
    assert kernel(path, 1.1, rects, 0, owners=[1, 0]) == {0: 0.0}
    # 0.3 m further out it does not touch
    rects[1, 1] += 0.31
    assert kernel(path, 1.1, rects, 0) == {}


@settings(max_examples=150, deadline=None)
@given(
    radius=st.sampled_from([math.inf, 15.0, -25.0, 60.0]),
    cars=st.lists(
        st.tuples(st.floats(-5, 35), st.floats(-6, 6), st.floats(-math.pi, math.pi)),
        min_size=1, max_size=6,
    ),
)  # fmt: skip
def test_same_rectangles_and_gaps_as_shapely(radius, cars):
    path, samples, s = arc(radius, 25.0, 0.5)
    rects = np.array([[x, y, yaw, 4.5, 1.8] for x, y, yaw in cars])
    got, expected = kernel(path, 1.1, rects, -1), oracle(samples, s, 1.1, rects, -1)
    # shapely and the separating-axis test may disagree on a contact of zero area
    for k in set(got) ^ set(expected):
        assert _grazing(samples, 1.1, rects[k])
    for k in set(got) & set(expected):
        assert got[k] == expected[k] or _grazing(samples, 1.1, rects[k])


def _grazing(samples, half_width, rect) -> bool:
    polygon = Polygon(rectangle_corners(rect[None, :])[0])
    corridor = [slice_polygon(a, b, half_width) for a, b in itertools.pairwise(samples)]
    return min(p.distance(polygon) for p in corridor) < 1e-6 or any(
        0 < p.intersection(polygon).area < 1e-6 for p in corridor
    )


def swept_body(samples: np.ndarray, step: float, body_m: float, half_width: float):
    """What a body `body_m` long sweeps while its front bumper runs along the samples,
    its back on them `body_m` behind (SUMO draws a car from its back to its front)."""
    back = round(body_m / step)
    return unary_union(
        [
            slice_polygon(samples[i - back], samples[i], half_width)
            for i in range(back, len(samples))
        ]
    )


def test_the_inside_of_a_turn_swept_by_the_body_is_part_of_the_corridor():
    """A 4.5 m car turning left on a 6 m radius: its middle runs 0.44 m inside its front
    bumper's path. A post standing 0.25 m into that bulge, outside the front's corridor
    (1.1 m each side), is in the way only when the body is taken into account."""
    path, samples, _ = arc(6.0, 9.0, 0.25)
    angle = 4.5 / 6.0  # beside the path's point 4.5 m along, inside the turn
    centre = 6.0 - 1.1 - 0.44 + 0.25 - 0.25  # the post's outer face 0.25 m into the bulge
    post = [centre * math.sin(angle), 6.0 - centre * math.cos(angle), angle - math.pi / 2]
    rect = np.array([[*post, 0.5, 0.5]])
    polygon = Polygon(rectangle_corners(rect)[0])
    assert swept_body(samples, 0.25, 4.5, 1.1).intersection(polygon).area > 0.1
    assert kernel(path, 1.1, rect, -1) == {}
    assert set(kernel(path, 1.1, rect, -1, body_m=4.5)) == {0}


@settings(max_examples=150, deadline=None)
@given(
    radius=st.sampled_from([6.0, -8.0, 15.0, math.inf]),
    cars=st.lists(
        st.tuples(st.floats(-3, 14), st.floats(-8, 8), st.floats(-math.pi, math.pi)),
        min_size=1, max_size=6,
    ),
)  # fmt: skip
def test_no_car_in_the_swept_body_is_missed(radius, cars):
    """Against shapely: every rectangle reaching more than 2 cm into what the body sweeps
    on a tight arc ahead of the front bumper's start (behind it is the body's place
    now, not the corridor's) is found; on a straight the body adds nothing."""
    path, samples, _ = arc(radius, 14.0, 0.25)
    rects = np.array([[x, y, yaw, 4.5, 1.8] for x, y, yaw in cars])
    got = kernel(path, 1.1, rects, -1, body_m=4.5)
    swept = swept_body(samples, 0.25, 4.5, 1.1).difference(box(-10.0, -3.0, 0.0, 3.0))
    for k, polygon in enumerate(Polygon(c) for c in rectangle_corners(rects)):
        if swept.intersection(polygon).area > 0.02 * 1.8:
            assert k in got
    if math.isinf(radius):
        assert got == kernel(path, 1.1, rects, -1)


def test_a_car_crossing_ahead_is_no_obstacle_if_it_has_left_before_arrival():
    # 10 m ahead at 5 m/s: 2 s to get there; a 4.5 x 1.8 m car crossing at right angles
    # at 10 m/s clears a 2.2 m corridor in 0.67 s (and braking at 4.5 m/s² it would
    # still cross 11 m); standing, or at 1 m/s (6.7 s), it is in the way; one driving
    # along the corridor never clears it
    assert crosses_before_arrival(10.0, 5.0, 2.2, 10.0, 0.0, 4.5, 1.8)
    assert not crosses_before_arrival(10.0, 5.0, 2.2, 0.0, 0.0, 4.5, 1.8)
    assert not crosses_before_arrival(10.0, 5.0, 2.2, 1.0, 0.0, 4.5, 1.8)
    assert not crosses_before_arrival(10.0, 5.0, 2.2, 10.0, 1.0, 4.5, 1.8)
    # standing still, this vehicle lets every crossing car pass that cannot stop in the way
    assert crosses_before_arrival(10.0, 0.0, 2.2, 8.0, 0.0, 4.5, 1.8)
    # at 5 m/s sideways a crossing car could still stop inside the corridor (2.8 m)
    assert not crosses_before_arrival(10.0, 0.0, 2.2, 5.0, 0.0, 4.5, 1.8)


# ---------------------------------------------------------------- sidesteps

#: A straight path along +x in a 3.2 m lane; a car 1.8 m wide (corridor 1.1 m each side
#: with its 0.2 m margin) with its front bumper at s 10, on the path.
STRAIGHT = RoutePath.from_pieces(
    [np.array([[0.0, 0.0], [100.0, 0.0]])], ["e_0"], [14.0], [3.2], 0.5
)


def sidestep(rect, offset_m=0.0):
    return sidestep_clearing(STRAIGHT, 10.0, offset_m, 20.0, 1.1, 0.9, np.array(rect))


def test_a_sidestep_clears_a_car_reaching_in_from_one_side():
    """Its side 0.15 m inside the body's left edge (y 0.75): the corridor's left edge
    goes to 0.75 - 0.05, a shift of -0.4 m; from the right, the mirror image."""
    assert sidestep((15.0, 1.65, 0.0, 4.5, 1.8)) == pytest.approx(-0.4, abs=0.01)
    assert sidestep((15.0, -1.65, 0.0, 4.5, 1.8)) == pytest.approx(0.4, abs=0.01)
    assert sidestep((15.0, 1.65, 0.0, 4.5, 1.8), offset_m=-0.1) == pytest.approx(-0.3, abs=0.01)


def test_no_sidestep_across_the_middle_beyond_the_lane_or_behind_the_front():
    assert sidestep((15.0, 0.0, 1.2, 4.5, 1.8)) == 0.0  # across the corridor
    assert sidestep((15.0, 1.1, 0.0, 4.5, 1.8)) == 0.0  # 0.7 m in: beyond the lane's room
    assert sidestep((5.0, 1.65, 0.0, 4.5, 1.8)) == 0.0  # beside the body, not ahead


def _crosses_one(gap, speed, width, other_speed, cos, other_length, other_width):
    """The rule for one hit, written out: sideways speed, the body's extent across the
    corridor, can it stop in it, is it through first."""
    sin = math.sqrt(max(1.0 - cos * cos, 0.0))
    sideways = other_speed * sin
    if sideways <= 0.0:
        return False
    across = width + other_length * sin + other_width * abs(cos)
    if sideways**2 / (2.0 * CROSSING_DECEL_MPS2) < across:
        return False
    return across / sideways < gap / max(speed, 1e-3)


_HIT = st.tuples(
    st.floats(0.0, 60.0), st.floats(0.0, 20.0), st.floats(0.5, 4.0), st.floats(0.0, 20.0),
    st.floats(-1.0, 1.0), st.floats(0.3, 18.0), st.floats(0.3, 3.0),
)  # fmt: skip
"""(gap, speed, corridor width, other's speed, cos of its heading, its length, width)"""


@settings(max_examples=200, deadline=None)
@given(st.lists(_HIT, min_size=1, max_size=20))
def test_the_crossing_rule_over_many_hits_is_the_rule_for_each(hits):
    """The obstacles stage decides all of a step's hits in one call: each answer is the
    one the rule gives that hit alone."""
    columns = [np.array(c) for c in zip(*hits, strict=True)]
    got = crosses_before_arrival(*columns)
    assert got.tolist() == [_crosses_one(*hit) for hit in hits]
