"""Exact analytic cases, REP 117 edge cases, batching and exclusion of cast_rays/scan_many."""

from __future__ import annotations

import math

import numpy as np
import pytest

from platoon_sumo.sensors import LASER_PRESETS, LaserConfig, cast_rays, scan_many

TOL_M = 1e-9


def fan(samples: int = 181, half_rad: float = 1.2, rmin: float = 0.0, rmax: float = 50.0):
    return LaserConfig(-half_rad, half_rad, samples, rmin, rmax)


@pytest.mark.parametrize("distance_m", [0.5, 3.0, 17.25])
@pytest.mark.parametrize("heading", [0.0, 0.7, -2.9])
def test_perpendicular_wall_reads_d_over_cos(distance_m: float, heading: float) -> None:
    config = fan()
    origin = np.array([1.5, -2.0])
    c, s = math.cos(heading), math.sin(heading)
    centre = origin + distance_m * np.array([c, s])
    half = 1000.0  # a wall much wider than the fan's footprint
    wall = [
        [centre[0] - half * s, centre[1] + half * c, centre[0] + half * s, centre[1] - half * c]
    ]
    ranges = cast_rays(origin, heading, config, segments=wall)
    expected = distance_m / np.cos(config.angles_rad)
    np.testing.assert_allclose(ranges, expected, rtol=0, atol=TOL_M)


@pytest.mark.parametrize("flip", [0.0, math.pi])  # the box may face either way
@pytest.mark.parametrize("heading", [0.0, 0.4, -2.2])
def test_box_straight_ahead_reads_centre_distance_minus_half_length(
    flip: float, heading: float
) -> None:
    config = LaserConfig(-0.5, 0.5, 3, 0.0, 40.0)  # middle ray along the heading
    origin = np.array([-3.0, 7.0])
    centre_dist, length, width = 12.0, 4.5, 1.8
    centre = origin + centre_dist * np.array([math.cos(heading), math.sin(heading)])
    rect = [[centre[0], centre[1], heading + flip, length, width]]
    ranges = cast_rays(origin, heading, config, rectangles=rect)
    assert abs(ranges[1] - (centre_dist - length / 2)) <= TOL_M


def test_ray_grazing_a_box_side_hits_the_corner() -> None:
    """Exactly representable geometry: the 0 rad ray runs along the box's lower side."""
    config = LaserConfig(-math.pi / 2, math.pi / 2, 3, 0.0, 20.0)  # rays at -90, 0, +90 deg
    box = [[7.0, 1.0, 0.0, 4.0, 2.0]]  # x in [5, 9], y in [0, 2]
    ranges = cast_rays([0.0, 0.0], 0.0, config, rectangles=box)
    assert ranges[1] == pytest.approx(5.0, abs=TOL_M)
    assert ranges[0] == np.inf and ranges[2] == np.inf


def test_segment_seen_end_on_is_hit_at_its_near_end() -> None:
    config = LaserConfig(-math.pi / 2, math.pi / 2, 3, 0.0, 20.0)
    ranges = cast_rays([0.0, 0.0], 0.0, config, segments=[[8.0, 0.0, 3.0, 0.0]])
    assert ranges[1] == pytest.approx(3.0, abs=TOL_M)
    assert np.isposinf(ranges[[0, 2]]).all()


@pytest.mark.parametrize("bearing", [-2.0, -1.0, 0.3, 2.5])
def test_wall_along_a_ray_at_any_bearing_reads_its_near_end_or_nothing(bearing) -> None:
    # its ends lie on the ray's bearing only to rounding: the distance between their
    # bearings once divided rounding by rounding and put the wall nearer than it is
    config = LaserConfig(bearing, bearing + 1.0, 2, 0.0, 3.0)
    for near_m in np.linspace(0.2, 2.9, 28):
        for far_m in (near_m + 0.05, near_m + 0.8, 3.9):
            for a, b in ((near_m, far_m), (far_m, near_m)):
                wall = [a * math.cos(bearing), a * math.sin(bearing)]
                wall += [b * math.cos(bearing), b * math.sin(bearing)]
                ranges = cast_rays([0.0, 0.0], 0.0, config, segments=[wall])
                assert ranges[1] == np.inf, (near_m, far_m)
                assert ranges[0] == np.inf or abs(ranges[0] - near_m) <= TOL_M, (a, b, ranges)


def test_obstacles_behind_and_beyond_range_are_not_seen() -> None:
    config = fan(rmax=10.0)
    boxes = [[-5.0, 0.0, 0.0, 2.0, 2.0], [10.5, 0.0, 0.0, 0.5, 30.0]]  # behind; just too far
    assert np.isposinf(cast_rays([0.0, 0.0], 0.0, config, rectangles=boxes)).all()


def test_first_surface_closer_than_range_min_is_minus_inf_even_with_one_behind() -> None:
    config = LaserConfig(-0.1, 0.1, 5, 0.3, 3.0)
    walls = [[0.2, -5.0, 0.2, 5.0], [1.0, -5.0, 1.0, 5.0]]
    assert np.isneginf(cast_rays([0.0, 0.0], 0.0, config, segments=walls)).all()
    only_far = cast_rays([0.0, 0.0], 0.0, config, segments=walls[1:])
    np.testing.assert_allclose(only_far, 1.0 / np.cos(config.angles_rad), atol=TOL_M)


def test_sensor_inside_a_rectangle_sees_its_inner_walls() -> None:
    box = [[0.0, 0.0, 0.0, 4.0, 2.0]]  # x in [-2, 2], y in [-1, 1]
    config = LaserConfig(0.0, math.pi, 3, 0.0, 10.0)  # 0, 90, 180 deg
    ranges = cast_rays([0.5, 0.0], 0.0, config, rectangles=box)
    np.testing.assert_allclose(ranges, [1.5, 1.0, 2.5], atol=TOL_M)
    too_close = LaserConfig(0.0, math.pi, 3, 3.0, 10.0)
    assert np.isneginf(cast_rays([0.5, 0.0], 0.0, too_close, rectangles=box)).all()


def test_sensor_on_a_surface_reads_zero() -> None:
    wall = [[0.0, -1.0, 0.0, 1.0]]
    zero_min = LaserConfig(-1.0, 1.0, 7, 0.0, 5.0)
    assert (cast_rays([0.0, 0.25], 0.0, zero_min, segments=wall) == 0.0).all()
    assert np.isneginf(cast_rays([0.0, 0.25], 0.0, fan(rmin=0.1), segments=wall)).all()


def test_full_circle_scan_wraps_around_the_seam() -> None:
    config = LaserConfig(-math.pi, math.pi, 361, 0.0, 30.0)
    box = [[-6.0, 0.0, 0.0, 2.0, 4.0]]  # straddles the +-pi seam, directly behind
    ranges = cast_rays([0.0, 0.0], 0.0, config, rectangles=box)
    assert ranges[0] == pytest.approx(5.0, abs=TOL_M)
    assert ranges[-1] == pytest.approx(5.0, abs=TOL_M)
    assert np.isposinf(ranges[180])
    hit = np.isfinite(ranges)
    expected = 5.0 / np.abs(np.cos(config.angles_rad[hit]))
    np.testing.assert_allclose(ranges[hit], expected, atol=TOL_M)


def test_no_obstacles_and_empty_inputs() -> None:
    config = LASER_PRESETS["paper_leader"]
    assert np.isposinf(cast_rays([0, 0], 0.0, config)).all()
    assert np.isposinf(cast_rays([0, 0], 0.0, config, np.empty((0, 5)), np.empty((0, 4)))).all()
    assert scan_many(np.empty((0, 2)), np.empty(0), config).shape == (0, 720)


def test_bad_obstacle_shapes_are_rejected() -> None:
    config = LASER_PRESETS["paper_leader"]
    with pytest.raises(ValueError, match="rectangles"):
        cast_rays([0, 0], 0.0, config, rectangles=[[1.0, 2.0, 3.0]])
    with pytest.raises(ValueError, match="segments"):
        cast_rays([0, 0], 0.0, config, segments=[[1.0, 2.0]])
    with pytest.raises(ValueError, match="headings"):
        scan_many([[0, 0], [1, 1]], [0.0], config)
    with pytest.raises(ValueError, match="exclude"):
        scan_many([[0, 0], [1, 1]], [0.0, 1.0], config, exclude=[0])


def city(rng: np.random.Generator, n: int, size_m: float):
    """Car-sized boxes scattered over a square, plus walls of every length."""
    rects = np.column_stack(
        (
            rng.uniform(0, size_m, n),
            rng.uniform(0, size_m, n),
            rng.uniform(-math.pi, math.pi, n),
            rng.uniform(3.5, 12.0, n),
            rng.uniform(1.6, 2.6, n),
        )
    )
    starts = rng.uniform(0, size_m, (60, 2))
    lengths = rng.choice([0.0, 0.5, 5.0, 80.0, 400.0], 60)
    angle = rng.uniform(-math.pi, math.pi, 60)
    ends = starts + lengths[:, None] * np.column_stack((np.cos(angle), np.sin(angle)))
    return rects, np.hstack((starts, ends))


@pytest.mark.parametrize("preset", ["utm30lx", "paper_leader", "paper_follower"])
def test_scan_many_equals_cast_rays_per_sensor(preset: str) -> None:
    rng = np.random.default_rng(11)
    config = LASER_PRESETS[preset]
    scale = config.range_max_m
    rects, segs = city(rng, 300, 20.0 * scale)
    if scale < 5.0:  # robot scale: robot-sized boxes
        rects[:, 3:] *= 0.05
    origins = rng.uniform(0, 20.0 * scale, (60, 2))
    origins[:5] = rects[:5, :2]  # some sensors sit inside a box
    headings = rng.uniform(-math.pi, math.pi, 60)
    batch = scan_many(origins, headings, config, rects, segs)
    assert batch.shape == (60, config.samples)
    for k in range(60):
        single = cast_rays(origins[k], headings[k], config, rects, segs)
        np.testing.assert_array_equal(batch[k], single)
    assert np.isfinite(batch).any()


def test_exclude_removes_the_own_vehicle_only() -> None:
    rng = np.random.default_rng(3)
    config = LASER_PRESETS["utm30lx"]
    rects, segs = city(rng, 400, 300.0)
    own = rng.choice(len(rects), 50, replace=False)
    yaw = rects[own, 2]
    # sensor exactly on the front bumper centre, looking ahead
    front = rects[own, :2] + 0.5 * rects[own, 3:4] * np.column_stack((np.cos(yaw), np.sin(yaw)))
    exclude = own.copy()
    exclude[-5:] = -1  # these keep their own box
    batch = scan_many(front, yaw, config, rects, segs, exclude=exclude)
    for k in range(50):
        scene = np.delete(rects, own[k], axis=0) if exclude[k] >= 0 else rects
        np.testing.assert_array_equal(batch[k], cast_rays(front[k], yaw[k], config, scene, segs))
