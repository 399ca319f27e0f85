"""The actuation a platoon gets when its scenario names none: the vehicle model's
`default_actuation` (cars: sublane, robots: planar), checked like a named one and
written into the results' copy of the scenario."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from platoon_sumo.errors import ScenarioError
from platoon_sumo.scenario import PlatoonConfig, VehicleConfig, load_scenario, prepare
from platoon_sumo.vehicles import VEHICLE_MODELS
from tests.helpers import URBAN_GRID_NET

ROUTE = {"edges": ["A1B1", "B1C1"]}


@pytest.mark.parametrize(
    ("model", "named", "expected"),
    [("bicycle", None, "sublane"), ("unicycle", None, "planar"), ("bicycle", "lane", "lane"),
     ("bicycle", "planar", "planar"), ("unicycle", "sublane", "sublane")],
)  # fmt: skip
def test_an_unset_actuation_is_the_vehicle_models_default(model, named, expected):
    config = PlatoonConfig(id="p", route=ROUTE, vehicle=VehicleConfig(model=model), actuation=named)
    assert config.actuation_name == expected == config.actuation


def test_a_model_without_a_default_gets_planar(monkeypatch: pytest.MonkeyPatch):
    """A plug-in vehicle model written before `default_actuation` existed."""

    class Legacy:
        name = "bicycle"

    monkeypatch.setattr(VEHICLE_MODELS, "get", lambda name: Legacy)
    assert PlatoonConfig(id="p", route=ROUTE).actuation_name == "planar"


def _scenario(tmp_path: Path, platoon: dict[str, Any], **extra: Any) -> Path:
    data = {
        "simulation": {"step_s": 0.1, "end_s": 120.0, "seed": 1, "lateral_resolution_m": None},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{"id": "p", "route": ROUTE, **platoon}],
        **extra,
    }
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def test_a_flow_template_with_the_cars_default_needs_the_sublane_model(tmp_path: Path):
    """Flows' platoons are checked too: a template naming no actuation is sublane."""
    flow = {"from_edge": "A1B1", "to_edge": "B1C1", "vehs_per_hour": 600, "end_s": 120.0,
            "platoon_share": 0.5, "platoon_template": "p"}  # fmt: skip
    flows = {"flows": [flow]}
    path = _scenario(tmp_path, {"template": True, "members": 2}, traffic=flows)
    with pytest.raises(ScenarioError) as err:
        prepare(load_scenario(path))
    assert err.value.key_path == "simulation.lateral_resolution_m"
    assert "sublane actuation" in str(err.value)


def test_the_results_copy_names_the_actuation_in_effect(tmp_path: Path):
    """A results folder's scenario repeats the run even if a later version changes the
    default (cars got planar until 2026-11-26)."""
    path = _scenario(tmp_path, {"members": 1, "actuation": None})
    data = yaml.safe_load(path.read_text())
    data["simulation"]["lateral_resolution_m"] = 0.8
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    source = load_scenario(path)
    copy = yaml.safe_load(source.reproducible_yaml(source.scenario.simulation))
    assert copy["platoons"][0]["actuation"] == "sublane"
