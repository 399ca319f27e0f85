"""Hit identities of cast_rays/scan_many (``return_hits=True``): which obstacle each
reading comes from, checked against the shapely oracle and on exact cases."""

from __future__ import annotations

import math

import hypothesis.strategies as st
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from shapely.geometry import Point

from platoon_sumo.sensors import LASER_PRESETS, LaserConfig, cast_rays, scan_many
from tests.sensors.laser_oracle import first_hits_per_obstacle, outlines
from tests.sensors.test_raycast_cases import city
from tests.sensors.test_raycast_oracle import GRAZE_M, TURN_RAD, scenes

TOL_M = 1e-9
#: Spread of the perturbed answers below which a (ray, obstacle) pair counts as well-posed
#: (the same rule as test_raycast_oracle.check_against_oracle).
WELL_POSED_M = 1e-4

finite = {"allow_nan": False, "allow_infinity": False}


def bits(a: np.ndarray) -> bytes:
    """The exact bytes of an array: equal only if bit-identical (signed zeros, NaNs)."""
    return np.ascontiguousarray(a).tobytes()


def unexcluded(hits: np.ndarray, own: int) -> np.ndarray:
    """Identities of a scene with rectangle ``own`` deleted, as indices of the full scene."""
    if own < 0:
        return hits
    return np.where(hits >= own, hits + 1, hits)


# --------------------------------------------------------------------- oracle properties


def per_obstacle_oracle(config, origin, heading, rects, segs):
    """Exact distance of every obstacle alone on every ray, shape (R + S, samples), and
    the low/high bracket of that distance under the oracle tests' perturbations."""
    length = 4.0 * config.range_max_m + 200.0
    angles = config.angles_rad
    geoms = outlines(rects, segs)
    exact = first_hits_per_obstacle(origin, heading, angles, geoms, length)
    variants = np.stack(
        (
            exact,
            first_hits_per_obstacle(
                origin, heading, angles, outlines(rects, segs, GRAZE_M), length
            ),
            first_hits_per_obstacle(
                origin, heading, angles, outlines(rects, segs, -GRAZE_M), length
            ),
            first_hits_per_obstacle(origin, heading + TURN_RAD, angles, geoms, length),
            first_hits_per_obstacle(origin, heading - TURN_RAD, angles, geoms, length),
        )
    )
    return exact, variants.min(axis=0), variants.max(axis=0)


def check_hits_against_oracle(config, origin, heading, rects, segs) -> None:
    """Every reading's identity is an obstacle that, cast alone by the oracle, is at the
    reading's distance, with no obstacle nearer; rays without a return carry -1."""
    ranges, hits = cast_rays(origin, heading, config, rects, segs, return_hits=True)
    assert hits.shape == ranges.shape == (config.samples,)
    assert hits.dtype == np.intp
    assert bits(ranges) == bits(cast_rays(origin, heading, config, rects, segs))
    n_obj = rects.shape[0] + segs.shape[0]
    exact, low, high = per_obstacle_oracle(config, origin, heading, rects, segs)
    with np.errstate(invalid="ignore"):  # inf - inf where an obstacle is missed
        well_posed = (low == high) | (high - low <= WELL_POSED_M)
    # each obstacle's distance: exact where well-posed, else its lower and upper bounds
    far = np.where(well_posed, exact, high)
    near = np.where(well_posed, exact, low)
    for i in range(config.samples):
        label = int(hits[i])
        if ranges[i] == np.inf:
            assert label == -1, (i, label)
            continue
        assert 0 <= label < n_obj, (i, label, ranges[i])
        if ranges[i] == -np.inf:  # the labelled surface is closer than range_min
            assert near[label, i] <= config.range_min_m + TOL_M, (i, label, near[label, i])
            assert near[label, i] <= far[:, i].min() + TOL_M, (i, label)
            continue
        # the labelled obstacle alone gives this distance ...
        if well_posed[label, i]:
            assert abs(exact[label, i] - ranges[i]) <= TOL_M, (i, label, exact[label, i])
        else:
            assert low[label, i] - TOL_M <= ranges[i] <= high[label, i] + TOL_M, (i, label)
        # ... and no obstacle is nearer
        assert far[:, i].min() >= ranges[i] - TOL_M, (i, label, far[:, i].min(), ranges[i])


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenes())
def test_hit_identities_match_shapely_oracle(scene) -> None:
    config, origin, heading, rects, segs = scene
    sensor = Point(origin)  # as in the range oracle test: the sensor outside every obstacle
    for geom in outlines(rects, np.empty((0, 4)), GRAZE_M):
        assume(not geom.convex_hull.buffer(1e-6).contains(sensor))
    for geom in outlines(np.empty((0, 5)), segs, GRAZE_M):
        assume(geom.distance(sensor) > 1e-6)
    check_hits_against_oracle(config, origin, heading, rects, segs)


@st.composite
def batches(draw):
    """A scene plus up to 4 more sensors around it (some inside a rectangle), each
    possibly excluded from one rectangle."""
    config, origin, heading, rects, segs = draw(scenes())
    reach = 1.3 * config.range_max_m
    origins, headings, exclude = [origin], [heading], [-1]
    for _ in range(draw(st.integers(0, 4))):
        own = draw(st.integers(-1, rects.shape[0] - 1))
        if own >= 0 and draw(st.booleans()):
            origins.append(rects[own, :2].copy())  # inside its own vehicle
        else:
            origins.append(origin + [draw(st.floats(-reach, reach, **finite)) for _ in range(2)])
        headings.append(draw(st.floats(-math.pi, math.pi, **finite)))
        exclude.append(own)
    return config, np.array(origins), np.array(headings), rects, segs, np.array(exclude)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(batches())
def test_batched_hit_identities_equal_single_scans(batch) -> None:
    config, origins, headings, rects, segs, exclude = batch
    ranges, hits = scan_many(origins, headings, config, rects, segs, exclude, return_hits=True)
    assert hits.shape == ranges.shape == (len(origins), config.samples)
    assert bits(ranges) == bits(scan_many(origins, headings, config, rects, segs, exclude))
    for k, own in enumerate(exclude):
        scene = np.delete(rects, own, axis=0) if own >= 0 else rects
        r1, h1 = cast_rays(origins[k], headings[k], config, scene, segs, return_hits=True)
        assert bits(ranges[k]) == bits(r1)
        np.testing.assert_array_equal(hits[k], unexcluded(h1, int(own)))
        if own >= 0:
            assert not (hits[k] == own).any()


def test_dense_city_identities_equal_single_scans_and_own_is_never_seen() -> None:
    rng = np.random.default_rng(5)
    config = LASER_PRESETS["utm30lx"]
    rects, segs = city(rng, 400, 300.0)
    own = rng.choice(len(rects), 60, replace=False)
    yaw = rects[own, 2]
    front = rects[own, :2] + 0.5 * rects[own, 3:4] * np.column_stack((np.cos(yaw), np.sin(yaw)))
    exclude = own.copy()
    exclude[-6:] = -1
    ranges, hits = scan_many(front, yaw, config, rects, segs, exclude, return_hits=True)
    assert np.isfinite(ranges).mean() > 0.1
    assert (hits >= len(rects)).any() and ((hits >= 0) & (hits < len(rects))).any()
    for k in range(60):
        scene = np.delete(rects, own[k], axis=0) if exclude[k] >= 0 else rects
        r1, h1 = cast_rays(front[k], yaw[k], config, scene, segs, return_hits=True)
        assert bits(ranges[k]) == bits(r1)
        np.testing.assert_array_equal(hits[k], unexcluded(h1, int(exclude[k])))
    assert not (hits[:-6] == own[:-6, None]).any()


# ----------------------------------------------------------------------------- unit cases


def test_predecessor_partly_occluded_by_a_closer_car() -> None:
    config = LaserConfig(-0.6, 0.6, 241, 0.1, 40.0)
    predecessor = [20.0, 0.0, 0.0, 4.5, 1.8]  # straight ahead
    cut_in = [10.0, 1.0, 0.0, 4.5, 1.8]  # closer, covering the predecessor's left part
    far_left = [15.0, 8.0, 0.0, 4.5, 1.8]  # unrelated, in view
    rects = np.array([far_left, predecessor, cut_in])
    ranges, hits = cast_rays([0.0, 0.0], 0.0, config, rects, return_hits=True)
    on_pred, on_cut = hits == 1, hits == 2
    assert on_pred.sum() > 5 and on_cut.sum() > 5 and (hits == 0).sum() > 5
    alone = {j: cast_rays([0.0, 0.0], 0.0, config, rects[j : j + 1]) for j in range(3)}
    # the closer car wins wherever it is hit; the predecessor only where it is not
    np.testing.assert_array_equal(on_cut, np.isfinite(alone[2]))
    np.testing.assert_array_equal(on_pred, np.isfinite(alone[1]) & ~np.isfinite(alone[2]))
    np.testing.assert_array_equal(ranges[on_pred], alone[1][on_pred])
    np.testing.assert_array_equal(ranges[on_cut], alone[2][on_cut])
    # rays returning from the predecessor: what re-casting it alone used to count
    seen = np.isfinite(alone[1])
    assert on_pred.sum() == np.count_nonzero(np.abs(ranges[seen] - alone[1][seen]) <= 1e-6)
    assert (hits[~np.isfinite(ranges)] == -1).all()
    # the cut-in hides the predecessor's left side: what is still seen lies to its right
    assert config.angles_rad[on_pred].max() < config.angles_rad[on_cut].min()


def test_sensor_excluded_from_its_own_rectangle() -> None:
    config = LaserConfig(-math.pi, math.pi, 361, 0.0, 30.0)
    rects = np.array([[0.0, 0.0, 0.3, 4.5, 1.8], [12.0, 0.0, 0.0, 4.5, 1.8]])
    origins = np.array([[0.5, 0.1], [12.0, 0.0]])  # each inside its own car
    own = np.array([0, 1])
    with_own = scan_many(origins, [0.3, 0.0], config, rects, return_hits=True)[1]
    assert (with_own[0] == 0).all() and (with_own[1] == 1).all()  # inner walls everywhere
    ranges, hits = scan_many(origins, [0.3, 0.0], config, rects, exclude=own, return_hits=True)
    assert not (hits == own[:, None]).any()
    assert set(np.unique(hits[0])) == {-1, 1} and set(np.unique(hits[1])) == {-1, 0}
    np.testing.assert_array_equal(hits == -1, np.isposinf(ranges))


def test_wall_segment_is_labelled_after_the_rectangles() -> None:
    config = LaserConfig(-0.3, 0.3, 31, 0.0, 30.0)
    rects = np.array([[0.0, 20.0, 0.0, 4.5, 1.8], [-10.0, 0.0, 0.0, 4.5, 1.8]])  # out of view
    segs = np.array(
        [
            [0.0, 30.0, 5.0, 30.0],  # out of view
            [8.0, -50.0, 8.0, 50.0],  # the wall ahead
            [12.0, -50.0, 12.0, 50.0],  # behind it
        ]
    )
    ranges, hits = cast_rays([0.0, 0.0], 0.0, config, rects, segs, return_hits=True)
    assert (hits == len(rects) + 1).all()
    np.testing.assert_allclose(ranges, 8.0 / np.cos(config.angles_rad), atol=TOL_M)
    _, without_rects = cast_rays([0.0, 0.0], 0.0, config, segments=segs, return_hits=True)
    assert (without_rects == 1).all()


def test_dropouts_carry_no_identity_and_noise_keeps_the_clean_one() -> None:
    config = LaserConfig(-1.0, 1.0, 1081, 0.1, 30.0, noise_std_m=0.05, dropout_prob=0.2)
    clean_config = LaserConfig(-1.0, 1.0, 1081, 0.1, 30.0)
    rects = np.array([[6.0, -1.0, 0.2, 4.5, 1.8], [9.0, 3.0, -0.1, 4.5, 1.8]])
    wall = np.array([[14.0, -40.0, 14.0, 40.0]])
    clean, truth = cast_rays([0, 0], 0.0, clean_config, rects, wall, return_hits=True)
    assert set(np.unique(truth)) == {0, 1, 2}
    ranges, hits = cast_rays(
        [0, 0], 0.0, config, rects, wall, rng=np.random.default_rng(4), return_hits=True
    )
    dropped = np.isnan(ranges)
    assert 0.1 < dropped.mean() < 0.3
    np.testing.assert_array_equal(hits == -1, dropped | np.isposinf(ranges))
    np.testing.assert_array_equal(hits[~dropped], truth[~dropped])
    np.testing.assert_array_equal(np.isposinf(ranges), np.isposinf(clean) & ~dropped)


def test_minus_inf_readings_keep_their_identity() -> None:
    config = LaserConfig(-0.1, 0.1, 5, 0.3, 3.0)
    walls = [[0.2, -5.0, 0.2, 5.0], [1.0, -5.0, 1.0, 5.0]]
    ranges, hits = cast_rays([0.0, 0.0], 0.0, config, segments=walls, return_hits=True)
    assert np.isneginf(ranges).all() and (hits == 0).all()
    box = [[0.0, 0.0, 0.0, 4.0, 2.0]]  # sensor inside, every inner wall closer than 3 m
    too_close = LaserConfig(0.0, math.pi, 3, 3.0, 10.0)
    ranges, hits = cast_rays(
        [0.5, 0.0], 0.0, too_close, rectangles=box, segments=walls, return_hits=True
    )
    assert np.isneginf(ranges).all()
    # 0 deg: the x = 1 wall (0.5 m) before the box; 90 deg: the box (1 m); 180 deg: the
    # x = 0.2 wall (0.3 m) before the box
    np.testing.assert_array_equal(hits, [2, 0, 1])


def test_sensor_on_a_surface_reads_that_surface() -> None:
    walls = [[0.0, -1.0, 0.0, 1.0], [3.0, -9.0, 3.0, 9.0]]
    config = LaserConfig(-1.0, 1.0, 7, 0.0, 5.0)
    ranges, hits = cast_rays([0.0, 0.25], 0.0, config, segments=walls, return_hits=True)
    assert (ranges == 0.0).all() and (hits == 0).all()
    ranges, hits = cast_rays([0.0, 0.25], 0.0, config, segments=walls[::-1], return_hits=True)
    assert (ranges == 0.0).all() and (hits == 1).all()


@pytest.mark.parametrize("order", [[0, 1], [1, 0]])
def test_shared_corner_gives_the_lower_index(order: list[int]) -> None:
    """Exactly representable geometry: two boxes meet at (5, 0) on the 0 rad ray."""
    config = LaserConfig(-math.pi / 2, math.pi / 2, 3, 0.0, 20.0)  # rays at -90, 0, +90 deg
    boxes = np.array([[7.0, 1.0, 0.0, 4.0, 2.0], [7.0, -1.0, 0.0, 4.0, 2.0]])[order]
    ranges, hits = cast_rays([0.0, 0.0], 0.0, config, rectangles=boxes, return_hits=True)
    assert ranges[1] == 5.0 and hits[1] == 0
    assert list(hits[[0, 2]]) == [-1, -1]
    # a wall through the same corner, listed first, is after the rectangles: still box 0
    wall = [[5.0, 0.0, 5.0, -3.0]]
    _, hits = cast_rays([0.0, 0.0], 0.0, config, boxes, wall, return_hits=True)
    assert hits[1] == 0
    _, hits = cast_rays([0.0, 0.0], 0.0, config, segments=wall, return_hits=True)
    assert hits[1] == 0
    batched = scan_many([[0.0, 0.0]] * 3, [0.0] * 3, config, boxes, wall, return_hits=True)[1]
    assert (batched[:, 1] == 0).all()


def test_full_circle_scan_labels_across_the_seam() -> None:
    config = LaserConfig(-math.pi, math.pi, 361, 0.0, 30.0)
    boxes = [[20.0, 0.0, 0.0, 2.0, 2.0], [-6.0, 0.0, 0.0, 2.0, 4.0]]  # ahead; behind
    ranges, hits = cast_rays([0.0, 0.0], 0.0, config, rectangles=boxes, return_hits=True)
    assert hits[0] == 1 and hits[-1] == 1 and hits[180] == 0
    np.testing.assert_array_equal(hits == -1, np.isposinf(ranges))
    assert set(np.unique(hits)) == {-1, 0, 1}


def test_no_obstacles_and_empty_batches() -> None:
    config = LASER_PRESETS["paper_leader"]
    ranges, hits = cast_rays([0, 0], 0.0, config, return_hits=True)
    assert np.isposinf(ranges).all() and (hits == -1).all() and hits.dtype == np.intp
    ranges, hits = scan_many(np.empty((0, 2)), np.empty(0), config, return_hits=True)
    assert ranges.shape == hits.shape == (0, 720)


# ----------------------------------------------------------- ranges unchanged by the option


@pytest.mark.parametrize(
    "config",
    [
        LaserConfig(-2.0, 2.0, 1081, 0.2, 30.0),
        LaserConfig(-2.0, 2.0, 1081, 0.2, 30.0, noise_std_m=0.03),
        LaserConfig(-2.0, 2.0, 1081, 0.2, 30.0, noise_std_m=0.03, dropout_prob=0.1),
        LaserConfig(-math.pi, math.pi, 720, 0.0, 30.0, dropout_prob=0.05),
    ],
)
def test_ranges_and_rng_draws_do_not_depend_on_return_hits(config: LaserConfig) -> None:
    rng = np.random.default_rng(21)
    rects, segs = city(rng, 200, 150.0)
    origins = rng.uniform(0.0, 150.0, (40, 2))
    origins[:3] = rects[:3, :2]  # inside a box
    headings = rng.uniform(-math.pi, math.pi, 40)
    exclude = np.where(np.arange(40) < 3, np.arange(40), -1)

    a, b = np.random.default_rng(8), np.random.default_rng(8)
    plain = scan_many(origins, headings, config, rects, segs, exclude, rng=a)
    ranges, hits = scan_many(
        origins, headings, config, rects, segs, exclude, rng=b, return_hits=True
    )
    assert bits(plain) == bits(ranges)
    assert a.bit_generator.state == b.bit_generator.state
    assert (hits[:3] != np.arange(3)[:, None]).all()
    assert np.isfinite(ranges).any()

    for k in (0, 5, 17):
        a, b = np.random.default_rng(k), np.random.default_rng(k)
        plain = cast_rays(origins[k], headings[k], config, rects, segs, rng=a)
        single, _ = cast_rays(origins[k], headings[k], config, rects, segs, rng=b, return_hits=True)
        assert bits(plain) == bits(single)
        assert a.bit_generator.state == b.bit_generator.state
