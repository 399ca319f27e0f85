"""cast_rays against an independent shapely oracle on random scenes (property tests)."""

from __future__ import annotations

import math

import hypothesis.strategies as st
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from shapely.geometry import Point

from platoon_sumo.sensors import LaserConfig, cast_rays
from tests.sensors.laser_oracle import outlines, raw_first_hits, rep117

TOL_M = 1e-9
#: Scene perturbations that tell well-posed rays from grazing ones (see below).
GRAZE_M = 1e-7
TURN_RAD = 1e-9

finite = {"allow_nan": False, "allow_infinity": False}


@st.composite
def configs(draw) -> LaserConfig:
    angle_min = draw(st.floats(-math.pi, 0.0, **finite))
    span = draw(st.floats(0.05, 2.0 * math.pi, **finite))
    range_min = draw(st.floats(0.0, 2.0, **finite))
    range_max = range_min + draw(st.floats(0.5, 40.0, **finite))
    samples = draw(st.integers(2, 181))
    return LaserConfig(angle_min, angle_min + span, samples, range_min, range_max)


@st.composite
def scenes(draw):
    """A sensor, its config, and obstacles placed around it in polar coordinates, so
    some are behind it, beyond range_max or closer than range_min; some rectangles have
    a corner put exactly on a ray (grazing)."""
    config = draw(configs())
    origin = np.array([draw(st.floats(-5, 5, **finite)), draw(st.floats(-5, 5, **finite))])
    heading = draw(st.floats(-math.pi, math.pi, **finite))
    reach = 1.3 * config.range_max_m
    polar = st.tuples(st.floats(0.0, reach, **finite), st.floats(-math.pi, math.pi, **finite))
    rects = []
    for dist, bearing in draw(st.lists(polar, max_size=6)):
        yaw = draw(st.floats(-math.pi, math.pi, **finite))
        length, width = draw(st.floats(0.1, 6.0, **finite)), draw(st.floats(0.1, 3.0, **finite))
        rects.append(
            (
                origin[0] + dist * math.cos(bearing),
                origin[1] + dist * math.sin(bearing),
                yaw,
                length,
                width,
            )
        )
    angles = config.angles_rad
    for ray, dist, corner in draw(
        st.lists(
            st.tuples(
                st.integers(0, config.samples - 1),
                st.floats(0.2, reach, **finite),
                st.integers(0, 3),
            ),
            max_size=2,
        )
    ):
        yaw = draw(st.floats(-math.pi, math.pi, **finite))
        length, width = draw(st.floats(0.1, 6.0, **finite)), draw(st.floats(0.1, 3.0, **finite))
        a = heading + angles[ray]
        sx, sy = [(1, -1), (1, 1), (-1, 1), (-1, -1)][corner]
        cx = origin[0] + dist * math.cos(a)
        cy = origin[1] + dist * math.sin(a)
        ox, oy = -0.5 * sx * length, -0.5 * sy * width  # centre seen from that corner
        rects.append(
            (
                cx + ox * math.cos(yaw) - oy * math.sin(yaw),
                cy + ox * math.sin(yaw) + oy * math.cos(yaw),
                yaw,
                length,
                width,
            )
        )
    segs = []
    for (d1, b1), (d2, b2) in draw(st.lists(st.tuples(polar, polar), max_size=5)):
        segs.append(
            (
                origin[0] + d1 * math.cos(b1),
                origin[1] + d1 * math.sin(b1),
                origin[0] + d2 * math.cos(b2),
                origin[1] + d2 * math.sin(b2),
            )
        )
    rects_a = np.array(rects, float).reshape(-1, 5)
    segs_a = np.array(segs, float).reshape(-1, 4)
    return config, origin, heading, rects_a, segs_a


def check_against_oracle(config, origin, heading, rects, segs) -> int:
    """Assert agreement; return the number of ill-posed rays (only bracketed, not exact).

    A ray is ill-posed when a tiny change of the scene changes its answer: obstacles
    grown or shrunk by ``GRAZE_M``, or the ray turned by ``TURN_RAD`` (both the oracle
    and the kernel round, and a ray that grazes a corner or runs along an edge may hit
    or miss). Well-posed rays must match the oracle to ``TOL_M``; ill-posed rays must
    give an answer between the smallest and largest of the perturbed answers.
    """
    ours = cast_rays(origin, heading, config, rects, segs)
    assert ours.shape == (config.samples,)
    assert ours.dtype == np.float64
    length = 4.0 * config.range_max_m + 200.0
    angles = config.angles_rad
    geoms = outlines(rects, segs)
    exact = raw_first_hits(origin, heading, angles, geoms, length)
    variants = np.vstack(
        (
            exact,
            raw_first_hits(origin, heading, angles, outlines(rects, segs, GRAZE_M), length),
            raw_first_hits(origin, heading, angles, outlines(rects, segs, -GRAZE_M), length),
            raw_first_hits(origin, heading + TURN_RAD, angles, geoms, length),
            raw_first_hits(origin, heading - TURN_RAD, angles, geoms, length),
        )
    )
    low, high = variants.min(axis=0), variants.max(axis=0)
    expected = rep117(exact, config.range_min_m, config.range_max_m)
    lo_lim, hi_lim = config.range_min_m, config.range_max_m
    ill_posed = 0
    for i in range(config.samples):
        well_posed = (low[i] == high[i]) or (high[i] - low[i] <= 1e-4)
        near_limit = min(abs(exact[i] - lo_lim), abs(exact[i] - hi_lim)) <= TOL_M
        if well_posed and not near_limit:
            if np.isfinite(expected[i]):
                assert abs(ours[i] - expected[i]) <= TOL_M, (i, ours[i], expected[i])
            else:
                assert ours[i] == expected[i], (i, ours[i], expected[i])
            continue
        ill_posed += 1
        if np.isfinite(ours[i]):
            assert low[i] - TOL_M <= ours[i] <= high[i] + TOL_M, (i, ours[i], low[i], high[i])
        elif ours[i] == np.inf:
            assert high[i] >= hi_lim - TOL_M, (i, high[i])
        else:
            assert low[i] <= lo_lim + TOL_M, (i, low[i])
    return ill_posed


@pytest.mark.slow
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenes())
def test_cast_rays_matches_shapely_oracle(scene) -> None:
    config, origin, heading, rects, segs = scene
    # the bracket argument needs the sensor outside every (grown) rectangle
    sensor = Point(origin)
    for geom in outlines(rects, np.empty((0, 4)), GRAZE_M):
        assume(not geom.convex_hull.buffer(1e-6).contains(sensor))
    for geom in outlines(np.empty((0, 5)), segs, GRAZE_M):
        assume(geom.distance(sensor) > 1e-6)
    check_against_oracle(config, origin, heading, rects, segs)


def test_dense_random_scene_matches_oracle() -> None:
    """A busy 270 deg car-scale scene: many overlapping boxes, every ray is checked."""
    rng = np.random.default_rng(7)
    config = LaserConfig.preset("utm30lx", samples=541)
    n = 40
    dist, bearing = rng.uniform(2.0, 35.0, n), rng.uniform(-math.pi, math.pi, n)
    rects = np.column_stack(
        (
            dist * np.cos(bearing),
            dist * np.sin(bearing),
            rng.uniform(-math.pi, math.pi, n),
            rng.uniform(3.5, 12.0, n),
            rng.uniform(1.6, 2.6, n),
        )
    )
    segs = rng.uniform(-40.0, 40.0, (10, 4))
    assert check_against_oracle(config, np.zeros(2), 0.3, rects, segs) <= 5
