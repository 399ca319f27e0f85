"""The compiled ray caster (``kernels.raycast.candidate_edges`` / ``evaluate_edges``
behind ``scan_many`` and ``cast_rays``) against the numpy implementation it replaced
(``tests/sensors/reference_raycast.py``): the same readings and the same hit identities,
ray for ray, on random scenes built to hit the delicate cases: many sensors, overlapping
and duplicated footprints, sensors inside obstacles, on their edges and corners, static
segments (zero-length, end-on, through a sensor, long ones over many grid cells), rays
exactly through vertices, readings exactly at range_min / range_max, full-circle scans
across the 2 pi seam, exclusion of a sensor's own rectangle, noise and dropouts.
"""

from __future__ import annotations

import math

import hypothesis.strategies as st
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from platoon_sumo.geometry import rectangle_corners
from platoon_sumo.sensors import LASER_PRESETS, LaserConfig, cast_rays, raycast, scan_many
from tests.sensors import reference_raycast
from tests.sensors.test_raycast_cases import city

finite = {"allow_nan": False, "allow_infinity": False}


def reference(*args, **kwargs):
    """``reference_raycast.scan_many``, quiet about the divisions by zero that numpy
    reports (rays parallel to an edge: the same infinities and NaNs as the kernels')."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return reference_raycast.scan_many(*args, **kwargs)


def assert_same(got, want) -> None:
    """Readings equal (as values, NaN where NaN) and identities equal."""
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert got[0].dtype == np.float64 and got[1].dtype == np.intp


# ------------------------------------------------------------------------ random scenes


@st.composite
def configs(draw) -> LaserConfig:
    exact = draw(st.booleans())
    if exact:  # rays along the axes (and the diagonals): geometry meets them exactly
        angle_min, span, samples = draw(
            st.sampled_from(
                [
                    (-math.pi / 2, math.pi, 3),
                    (-math.pi, 2 * math.pi, 5),
                    (-math.pi, 2 * math.pi, 9),
                    (0.0, math.pi, 5),
                    (-math.pi / 4, math.pi / 2, 3),
                ]
            )
        )
    else:
        angle_min = draw(st.floats(-math.pi, 0.0, **finite))
        span = draw(st.floats(0.05, 2.0 * math.pi, **finite))
        samples = draw(st.integers(2, 150))
    range_min = draw(st.sampled_from([0.0, 0.0, 0.5, 1.0, 2.0]))
    range_max = range_min + draw(st.sampled_from([1.0, 3.0, 4.0, 7.5, 20.0, 30.0]))
    noise = draw(st.sampled_from([(0.0, 0.0), (0.0, 0.0), (0.02, 0.0), (0.02, 0.15)]))
    return LaserConfig(angle_min, angle_min + span, samples, range_min, range_max, *noise)


@st.composite
def scenes(draw):
    """A config, sensors (poses, own rectangles) and obstacles in a 30 m square. Half the
    scenes sit on the integer grid (axis-aligned boxes, segments and sensors at whole
    metres, headings 0 or 90 deg), where rays meet corners and ends exactly and readings
    land exactly on range_min / range_max."""
    config = draw(configs())
    grid = draw(st.booleans())
    coord = st.integers(-12, 12).map(float) if grid else st.floats(-12.0, 12.0, **finite)
    size = st.integers(1, 6).map(float) if grid else st.floats(0.1, 6.0, **finite)
    yaw = (
        st.sampled_from([0.0, math.pi / 2, math.pi, -math.pi / 2])
        if grid
        else st.floats(-math.pi, math.pi, **finite)
    )
    rects = [
        (draw(coord), draw(coord), draw(yaw), draw(size), draw(size))
        for _ in range(draw(st.integers(0, 12)))
    ]
    for i in draw(st.lists(st.integers(0, 11), max_size=3)):  # exact duplicates
        if i < len(rects):
            rects.append(rects[i])
    segs = [
        (draw(coord), draw(coord), draw(coord), draw(coord)) for _ in range(draw(st.integers(0, 6)))
    ]
    for i in draw(st.lists(st.integers(0, 11), max_size=2)):  # a rectangle's edge as a wall
        if i < len(rects):
            corners = rectangle_corners(np.array(rects[i]))[0]
            j = draw(st.integers(0, 3))
            segs.append((*corners[j], *corners[(j + 1) % 4]))
    sensors, headings, own = [], [], []
    for _ in range(draw(st.integers(1, 8))):
        where = draw(st.sampled_from(["free", "free", "inside", "corner", "segment", "same"]))
        x, y, mine = draw(coord), draw(coord), -1
        if where == "inside" and rects:
            mine = draw(st.integers(0, len(rects) - 1))
            x, y = rects[mine][0], rects[mine][1]
            if draw(st.booleans()):
                mine = -1  # inside a rectangle that is not its own
        elif where == "corner" and rects:
            i = draw(st.integers(0, len(rects) - 1))
            corners = rectangle_corners(np.array(rects[i]))[0]
            x, y = corners[draw(st.integers(0, 3))]
        elif where == "segment" and segs:
            x1, y1, x2, y2 = segs[draw(st.integers(0, len(segs) - 1))]
            x, y = draw(st.sampled_from([(x1, y1), (x2, y2), (0.5 * (x1 + x2), 0.5 * (y1 + y2))]))
        elif where == "same" and sensors:
            x, y = sensors[-1]
        sensors.append((x, y))
        headings.append(draw(yaw))
        if mine < 0 and rects and draw(st.booleans()):
            mine = draw(st.integers(0, len(rects) - 1))
        own.append(mine)
    for k in draw(st.lists(st.integers(0, 7), max_size=2)):  # a segment end-on to a sensor
        if k < len(sensors):
            x, y = sensors[k]
            a = headings[k] + config.angles_rad[draw(st.integers(0, config.samples - 1))]
            d1, d2 = draw(st.floats(0.0, 15.0, **finite)), draw(st.floats(0.0, 15.0, **finite))
            c, s = math.cos(a), math.sin(a)
            segs.append((x + d1 * c, y + d1 * s, x + d2 * c, y + d2 * s))
    return (
        config,
        np.array(sensors, float).reshape(-1, 2),
        np.array(headings, float),
        np.array(rects, float).reshape(-1, 5),
        np.array(segs, float).reshape(-1, 4),
        np.array(own, dtype=np.intp),
    )


@pytest.mark.slow
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenes(), st.integers(0, 2**32 - 1))
def test_scan_many_equals_the_numpy_implementation(scene, seed: int) -> None:
    config, sensors, headings, rects, segs, own = scene
    exclude = own if seed % 3 else None
    got = scan_many(
        sensors, headings, config, rects, segs, exclude, rng=np.random.default_rng(seed),
        return_hits=True,
    )  # fmt: skip
    want = reference(
        sensors, headings, config, rects, segs, exclude, rng=np.random.default_rng(seed),
        return_hits=True,
    )  # fmt: skip
    assert_same(got, want)
    plain = scan_many(
        sensors, headings, config, rects, segs, exclude, rng=np.random.default_rng(seed)
    )
    np.testing.assert_array_equal(plain, got[0])


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenes())
def test_cast_rays_equals_the_numpy_implementation(scene) -> None:
    config, sensors, headings, rects, segs, _ = scene
    for k in range(min(len(sensors), 3)):
        got = cast_rays(
            sensors[k], headings[k], config, rects, segs, np.random.default_rng(k),
            return_hits=True,
        )  # fmt: skip
        want = reference(
            sensors[k], headings[k : k + 1], config, rects, segs,
            rng=np.random.default_rng(k), return_hits=True, use_grid=False,
        )  # fmt: skip
        assert_same((got[0][None], got[1][None]), want)


# ------------------------------------------------------------------ larger fixed scenes


@pytest.mark.parametrize("preset", ["utm30lx", "paper_leader", "paper_follower"])
@pytest.mark.parametrize("seed", [1, 2])
def test_city_batches_equal_the_numpy_implementation(preset: str, seed: int) -> None:
    """Hundreds of sensors among crowded boxes and walls of every length (some crossing
    many grid cells), sensors inside boxes, exact duplicates (ties at every distance)."""
    rng = np.random.default_rng(seed)
    config = LASER_PRESETS[preset]
    scale = config.range_max_m
    rects, segs = city(rng, 400, 10.0 * scale)
    if scale < 5.0:  # robot scale
        rects[:, 3:] *= 0.05
        segs[:, 2:] = segs[:, :2] + 0.02 * (segs[:, 2:] - segs[:, :2])
    rects = np.vstack((rects, rects[::9]))
    segs = np.vstack((segs, segs[::7]))
    k = 300
    own = rng.choice(len(rects), k, replace=False)
    yaw = rects[own, 2]
    front = rects[own, :2] + 0.5 * rects[own, 3:4] * np.column_stack((np.cos(yaw), np.sin(yaw)))
    front[:20] = rects[own[:20], :2]  # inside their own box
    exclude = np.where(np.arange(k) % 5 == 4, -1, own)
    got = scan_many(front, yaw, config, rects, segs, exclude, return_hits=True)
    want = reference(front, yaw, config, rects, segs, exclude, return_hits=True)
    assert_same(got, want)
    assert (got[1] >= 0).mean() > 0.05


@pytest.mark.parametrize("rows_per_chunk", [7, 1 << 16])
def test_equal_to_the_chunked_numpy_run_evaluation(
    monkeypatch: pytest.MonkeyPatch, rows_per_chunk: int
) -> None:
    """The reference pipeline with its numpy run evaluation, however it chunks the rows,
    agrees with ``scan_many``."""
    rng = np.random.default_rng(3)
    config = LASER_PRESETS["utm30lx"]
    rects, segs = city(rng, 300, 200.0)
    origins = rng.uniform(0.0, 200.0, (60, 2))
    origins[:4] = rects[:4, :2]
    headings = rng.uniform(-math.pi, math.pi, 60)
    exclude = np.where(np.arange(60) % 2 == 0, np.arange(60), -1)
    got = scan_many(origins, headings, config, rects, segs, exclude, return_hits=True)
    monkeypatch.setattr(reference_raycast, "_ROWS_PER_CHUNK", rows_per_chunk)
    want = reference(origins, headings, config, rects, segs, exclude, return_hits=True)
    assert_same(got, want)


def test_scratch_tables_grow_and_are_reused() -> None:
    """A batch with more edges than the scratch tables hold, then a small one: both as
    the numpy implementation (the tables grow, and stale columns are never read)."""
    rng = np.random.default_rng(4)
    config = LASER_PRESETS["utm30lx"]
    rects, segs = city(rng, 600, 120.0)
    origins = rng.uniform(0.0, 120.0, (200, 2))
    headings = rng.uniform(-math.pi, math.pi, 200)
    for sl in (slice(None), slice(0, 3), slice(None)):
        got = scan_many(origins[sl], headings[sl], config, rects, segs, return_hits=True)
        want = reference(origins[sl], headings[sl], config, rects, segs, return_hits=True)
        assert_same(got, want)
    assert raycast._WORKSPACE.geo.shape[1] > 1024


def test_non_contiguous_inputs() -> None:
    rng = np.random.default_rng(6)
    config = LASER_PRESETS["paper_leader"]
    rects, segs = city(rng, 50, 20.0)
    rects[:, 3:] *= 0.2
    wide = np.zeros((30, 6))
    wide[:, ::3] = rng.uniform(0.0, 20.0, (30, 2))
    origins = wide[:, ::3]  # a strided view
    headings = rng.uniform(-math.pi, math.pi, 60)[::2]
    got = scan_many(origins, headings, config, np.asfortranarray(rects), segs.T.copy().T, None)
    want = reference(origins, headings, config, rects, segs)
    np.testing.assert_array_equal(got, want)
