"""A small study on the straight road: 2 parameters x 2 values x 2 seeds, 20 s runs."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import REPO

PLUGINS = REPO / "tests" / "plugins"
PARAMETERS = {
    "platoons[0].follower.params.time_gap_s": [0.8, 1.2],
    "platoons[0].leader.params.cruise_speed_mps": [8.0, 12.0],
}
METRICS = [
    "summary.overall.min_gap_m",
    "summary.traffic.network_mean_speed_mps",
    "platoons.max_abs_spacing_error_m:max",
    "vehicles.min_gap_m:min",
]


def scenario() -> dict:
    """Three cars behind a constant-speed leader among random traffic on the straight
    road (the seed decides the traffic)."""
    return {
        "simulation": {"step_s": 0.1, "end_s": 60, "seed": 1},
        "network": {"net_file": str(REPO / "networks/straight/straight.net.xml")},
        "traffic": {
            "flows": [{"from_edge": "WE", "to_edge": "WE", "vehs_per_hour": 900}],
            "vehicle_types": [{"id": "car", "speed_dev": 0.2}],
        },
        "platoons": [
            {
                "id": "p",
                "route": {"edges": ["WE"]},
                "members": 3,
                "depart_s": 2.0,
                "actuation": "lane",
                "leader": {"type": "route_following", "params": {"cruise_speed_mps": 10.0}},
                "follower": {"type": "laser_follower", "params": {"time_gap_s": 1.0}},
            }
        ],
        "outputs": {"metrics_start_s": 5.0},
    }


def write_study(folder: Path, **changes: object) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base.yaml").write_text(yaml.safe_dump(changes.pop("base", scenario())))
    study = {
        "scenario": "base.yaml",
        "parameters": PARAMETERS,
        "repetitions": 2,
        "seed": 11,
        "end_s": 20.0,
        "metrics": METRICS,
        **changes,
    }
    path = folder / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


@pytest.fixture
def plugins_everywhere(monkeypatch: pytest.MonkeyPatch) -> None:
    """The test plug-ins importable here and in every worker process."""
    monkeypatch.syspath_prepend(str(PLUGINS))
    monkeypatch.setenv("PYTHONPATH", str(PLUGINS))
