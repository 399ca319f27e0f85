"""validate warns when a laser follower's spacing policy outgrows its laser's range."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from platoon_sumo.cli import main
from tests.helpers import REPO


def _scenario(tmp_path: Path, cruise_mps: float, preset: str, time_gap_s: float = 1.2) -> Path:
    doc = {
        "simulation": {"step_s": 0.1, "end_s": 30, "seed": 1},
        "network": {"net_file": str(REPO / "networks/straight/straight.net.xml")},
        "platoons": [
            {
                "id": "fast",
                "route": {"edges": ["WE"]},
                "members": 3,
                "actuation": "lane",
                "vehicle": {"max_speed_mps": 40.0, "sumo_speed_factor": 1.0},
                "leader": {"type": "route_following", "params": {"cruise_speed_mps": cruise_mps}},
                "follower": {
                    "type": "laser_follower",
                    "params": {"time_gap_s": time_gap_s, "standstill_gap_m": 2.0},
                    "sensor": {"preset": preset},
                },
            }
        ],
    }
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_time_gap_beyond_the_laser_range_is_flagged(tmp_path, capfd):
    path = _scenario(tmp_path, cruise_mps=30.0, preset="utm30lx")
    assert main(["validate", str(path)]) == 0
    _, err = capfd.readouterr()
    (line,) = [x for x in err.splitlines() if "laser" in x]
    assert line.startswith(f"warning: {path}: platoons[0] ('fast')")
    # 2 m + 1.2 s x 27.78 m/s (the road's limit caps the 30 m/s cruise) = 35 m > 30 m
    assert "35 m at 27.8 m/s" in line and "30 m range" in line
    assert "above 23.3 m/s" in line and "platoons[0].follower.sensor" in line


@pytest.mark.parametrize(
    ("cruise", "preset", "time_gap"),
    [(30.0, "lidar_120m", 1.2), (15.0, "utm30lx", 1.2), (30.0, "utm30lx", 0.6)],
)
def test_a_policy_the_laser_covers_is_not_flagged(tmp_path, capfd, cruise, preset, time_gap):
    path = _scenario(tmp_path, cruise_mps=cruise, preset=preset, time_gap_s=time_gap)
    assert main(["validate", str(path)]) == 0
    _, err = capfd.readouterr()
    assert "laser" not in err


def _turning_scenario(tmp_path: Path, half_fov_rad: float) -> Path:
    """Laser followers through the urban grid's right and left turns, with a field of
    view of +-`half_fov_rad`."""
    doc = {
        "simulation": {"step_s": 0.1, "end_s": 30, "seed": 1},
        "network": {"net_file": str(REPO / "networks/urban_grid/urban_grid.net.xml")},
        "platoons": [
            {
                "id": "turning",
                "route": {"edges": ["left1A1", "A1B1", "B1B0", "B0A0", "A0left0"]},
                "members": 3,
                "follower": {
                    "type": "laser_follower",
                    "params": {"time_gap_s": 0.8},
                    "sensor": {
                        "preset": "utm30lx",
                        "overrides": {
                            "angle_min_rad": -half_fov_rad,
                            "angle_max_rad": half_fov_rad,
                        },
                    },
                },
            }
        ],
    }
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_field_of_view_too_narrow_for_the_routes_turns_is_flagged(tmp_path, capfd):
    path = _turning_scenario(tmp_path, half_fov_rad=0.2)  # +-11 deg, as the paper's scan
    assert main(["validate", str(path)]) == 0
    _, err = capfd.readouterr()
    (line,) = [x for x in err.splitlines() if "field of view" in x]
    assert line.startswith(f"warning: {path}: platoons[0] ('turning'): at ")
    assert "outside their laser's +-11 deg field of view" in line
    assert "platoons[0].follower.sensor" in line


def test_the_default_scanner_sees_round_the_grid_turns(tmp_path, capfd):
    path = _turning_scenario(tmp_path, half_fov_rad=2.356)  # the UTM-30LX's +-135 deg
    assert main(["validate", str(path)]) == 0
    _, err = capfd.readouterr()
    assert "field of view" not in err
