"""LaserConfig validation, presets, LaserScan metadata, mount poses and the PNG plot."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from platoon_sumo.sensors import (
    LASER_PRESETS,
    LaserConfig,
    LaserScan,
    cast_rays,
    plot_scan,
    sensor_poses,
)

GOOD = {
    "angle_min_rad": -1.0,
    "angle_max_rad": 1.0,
    "samples": 10,
    "range_min_m": 0.1,
    "range_max_m": 5.0,
}


@pytest.mark.parametrize(
    ("field", "value", "expected"),
    [
        ("angle_max_rad", -1.0, "> angle_min_rad"),
        ("angle_max_rad", -2.0, "> angle_min_rad"),
        ("angle_max_rad", 6.0, "2\\*pi"),
        ("samples", 1, "integer >= 2"),
        ("samples", 2.5, "integer >= 2"),
        ("range_min_m", -0.1, ">= 0"),
        ("range_max_m", 0.1, "> range_min_m"),
        ("noise_std_m", -0.01, ">= 0"),
        ("dropout_prob", 1.0, "\\[0, 1\\)"),
        ("dropout_prob", -0.1, "\\[0, 1\\)"),
        ("rate_hz", 0.0, "> 0"),
        ("range_max_m", math.inf, "finite"),
    ],
)
def test_invalid_config_names_field_and_expectation(field: str, value, expected: str) -> None:
    with pytest.raises(ValueError, match=f"LaserConfig.{field}: expected .*{expected}"):
        LaserConfig(**{**GOOD, field: value})


def test_full_circle_is_allowed_and_angles_include_both_ends() -> None:
    config = LaserConfig(-math.pi, math.pi, 5, 0.0, 1.0)
    np.testing.assert_allclose(config.angles_rad, [-math.pi, -math.pi / 2, 0, math.pi / 2, math.pi])
    assert config.angle_increment_rad == pytest.approx(math.pi / 2)


def test_presets_match_the_paper_and_the_utm30lx() -> None:
    leader, follower, utm = (
        LASER_PRESETS[k] for k in ("paper_leader", "paper_follower", "utm30lx")
    )
    assert (
        math.degrees(leader.angle_min_rad),
        math.degrees(leader.angle_max_rad),
    ) == pytest.approx((-90, 90))
    assert (leader.samples, leader.range_min_m, leader.range_max_m) == (720, 0.30, 3.0)
    assert math.degrees(follower.angle_max_rad) == pytest.approx(11.5)
    assert (follower.samples, follower.range_min_m, follower.range_max_m) == (720, 0.30, 1.0)
    assert math.degrees(utm.angle_max_rad) == pytest.approx(135)
    assert (utm.samples, utm.range_min_m, utm.range_max_m, utm.rate_hz) == (1081, 0.1, 30.0, 40.0)
    assert math.degrees(utm.angle_increment_rad) == pytest.approx(0.25)
    assert LaserConfig.preset("utm30lx") is utm
    assert LaserConfig.preset("utm30lx", noise_std_m=0.01).noise_std_m == 0.01


def test_unknown_preset_suggests_a_name() -> None:
    with pytest.raises(ValueError, match="did you mean 'utm30lx'"):
        LaserConfig.preset("utm30x")
    with pytest.raises(ValueError, match="unknown LaserConfig field"):
        LaserConfig.preset("utm30lx", noise_m=0.1)


def test_sensor_poses_apply_mount_relative_to_front_bumper() -> None:
    config = LaserConfig(**GOOD, mount_x_m=-1.0, mount_y_m=0.5, mount_yaw_rad=0.1)
    origins, headings = sensor_poses([10.0, 0.0], [5.0, 0.0], [math.pi / 2, 0.0], config)
    np.testing.assert_allclose(origins, [[9.5, 4.0], [-1.0, 0.5]], atol=1e-12)
    np.testing.assert_allclose(headings, [math.pi / 2 + 0.1, 0.1])


def test_laser_scan_carries_ros_fields_and_world_points() -> None:
    config = LaserConfig(-0.5, 0.5, 11, 0.1, 30.0, rate_hz=20.0)
    ranges = cast_rays([1.0, 2.0], 0.0, config, segments=[[6.0, -50.0, 6.0, 50.0]])
    scan = LaserScan.from_ranges(config, ranges, (1.0, 2.0), 0.0, stamp_s=3.5)
    assert (scan.angle_min, scan.angle_max, scan.range_min, scan.range_max) == (
        -0.5,
        0.5,
        0.1,
        30.0,
    )
    assert scan.scan_time == pytest.approx(0.05)
    assert scan.time_increment == 0.0 and scan.stamp_s == 3.5
    np.testing.assert_allclose(scan.points_world()[:, 0], 6.0, atol=1e-9)
    with pytest.raises(ValueError, match="ranges"):
        LaserScan.from_ranges(config, ranges[:-1], (1.0, 2.0), 0.0)


def test_plot_scan_writes_a_png(tmp_path) -> None:
    config = LaserConfig(-2.3, 2.3, 271, 0.3, 12.0, dropout_prob=0.05)
    rects = np.array([[5.0, 1.0, 0.3, 4.5, 1.8], [-3.0, -4.0, 1.2, 4.0, 1.7]])
    segs = np.array([[-10.0, 6.0, 10.0, 6.0]])
    ranges = cast_rays([0, 0], 0.2, config, rects, segs, rng=np.random.default_rng(0))
    scan = LaserScan.from_ranges(config, ranges, (0.0, 0.0), 0.2)
    out = plot_scan(scan, rects, segs, path=tmp_path / "scan.png")
    with open(out, "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n"


def test_importing_sensors_does_not_import_pyplot() -> None:
    code = "import sys, platoon_sumo.sensors; print('matplotlib.pyplot' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
