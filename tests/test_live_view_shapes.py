"""The live view's shapes (pure geometry) and its command-line checks, no display needed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from platoon_sumo.cli import main
from platoon_sumo.live_view import MAX_RAYS_DRAWN, SURFACE_JOIN_M, field_of_view, scan_shapes
from platoon_sumo.sensors.laser import LaserScan
from tests.helpers import REPO

SCENARIO = REPO / "scenarios" / "urban_platoon.yaml"


def scan(ranges: np.ndarray, heading_rad: float = 0.3) -> LaserScan:
    n = ranges.size
    increment = math.radians(270.0) / (n - 1)
    return LaserScan(
        -math.radians(135.0), math.radians(135.0), increment, 0.0, 0.025, 0.1, 30.0,
        ranges, 5.0, -2.0, heading_rad,
    )  # fmt: skip


def test_rays_go_from_the_sensor_to_each_hit_and_back() -> None:
    ranges = np.full(181, np.inf)
    ranges[40:60] = 10.0
    ranges[100] = 4.0
    ranges[120] = -np.inf  # too close: no return drawn
    ranges[130] = np.nan  # dropout
    s = scan(ranges)
    rays, _ = scan_shapes(s)
    assert rays.shape == (2 * 21, 2)
    np.testing.assert_allclose(rays[0::2], np.broadcast_to([5.0, -2.0], (21, 2)))
    hit_rays = np.flatnonzero(np.isfinite(ranges))
    angles = s.heading_rad + s.angle_min + s.angle_increment * hit_rays
    expected = np.column_stack([5.0 + ranges[hit_rays] * np.cos(angles),
                                -2.0 + ranges[hit_rays] * np.sin(angles)])  # fmt: skip
    np.testing.assert_allclose(rays[1::2], expected)


def test_surfaces_join_neighbouring_hits_only() -> None:
    ranges = np.full(181, np.inf)
    ranges[40:60] = 10.0  # one wall: hits 0.26 m apart
    ranges[60:70] = 20.0  # the next rays, 10 m farther: another surface
    ranges[100] = 4.0  # a lone hit: a tick across its ray
    _, surfaces = scan_shapes(scan(ranges))
    assert [len(s) for s in surfaces] == [20, 10, 2]
    for surface in surfaces[:2]:
        assert np.hypot(*np.diff(surface, axis=0).T).max() <= SURFACE_JOIN_M
    tick = surfaces[2]
    assert np.hypot(*(tick[1] - tick[0])) == pytest.approx(0.3)


def test_a_dense_scan_is_thinned_to_the_drawing_limit() -> None:
    rays, _ = scan_shapes(scan(np.full(1081, 12.0)))
    assert len(rays) // 2 <= MAX_RAYS_DRAWN


def test_field_of_view_is_closed_at_the_sensor_and_reaches_range_max() -> None:
    s = scan(np.full(181, np.inf))
    outline = field_of_view(s)
    np.testing.assert_allclose(outline[0], outline[-1])
    np.testing.assert_allclose(outline[0], [5.0, -2.0])
    reach = np.hypot(outline[1:-1, 0] - 5.0, outline[1:-1, 1] + 2.0)
    np.testing.assert_allclose(reach, s.range_max)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--gui", "--gui-vehicle", "nope"], "--gui-vehicle 'nope': no platoon vehicle"),
        (["--gui-vehicle", "cars.1"], "--gui-vehicle: only with --gui"),
        (["--gui", "--gui-delay", "-5"], "--gui-delay -5"),
    ],
)
def test_live_view_arguments_are_checked_before_anything_runs(
    tmp_path, capsys, monkeypatch, args, message
) -> None:
    monkeypatch.setenv("DISPLAY", ":99")  # the checks come before sumo-gui is started
    out = tmp_path / "out"
    assert main(["run", str(SCENARIO), "--out", str(out), *args]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_gui_without_a_display_says_how_to_get_one(tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    out = tmp_path / "out"
    assert main(["run", str(SCENARIO), "--out", str(out), "--gui"]) == 2
    assert "xvfb-run" in capsys.readouterr().err
    assert not out.exists()
