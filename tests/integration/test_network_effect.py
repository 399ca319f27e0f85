"""What the platoons do to everyone else: the same traffic with and without them."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from platoon_sumo.cli import main
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out


def test_human_travel_times_with_and_without_the_platoons(write_scenario, tmp_path):
    # a slow platoon ahead of a flow of SUMO cars on the same straight route
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 240.0, "seed": 5},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "traffic": {"flows": [{"from_edge": "left1A1", "to_edge": "C1right1",
                               "vehs_per_hour": 720, "begin_s": 5.0, "end_s": 120.0}]},
        "platoons": [{
            "id": "slow", "members": 4, "spacing_m": 8.0, "depart_s": 0.0,
            "route": {"from_edge": "left1A1", "to_edge": "C1right1"},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 3.0}},
            "follower": {"type": "route_following", "params": {"cruise_speed_mps": 3.0}},
        }],
    }  # fmt: skip
    path = write_scenario(scenario)
    with_dir = run(load_plan(path), tmp_path / "with").directory
    assert main(["run", str(path), "--no-platoons", "--out", str(tmp_path / "without"),
                 "--quiet"]) == 0  # fmt: skip
    with_platoons = json.loads((with_dir / "summary.json").read_text())
    without = json.loads((tmp_path / "without" / "summary.json").read_text())

    assert with_platoons["platoon_vehicles"]["departed"] == 4
    assert without["platoon_vehicles"]["planned"] == 0
    trips = pd.read_csv(tmp_path / "without" / "tripinfo.csv", sep=";")
    assert not trips["tripinfo_id"].str.startswith("slow.").any()
    a, b = with_platoons["traffic"], without["traffic"]
    # the same human demand, fully measured both times
    assert a["human_trips"] == b["human_trips"] > 15
    assert a["human_trips_finished"] == a["human_trips"]
    for key in ("human_mean_travel_time_s", "human_mean_time_loss_s"):
        assert a[key] > 0.0 and b[key] > 0.0, key
    # the slow platoon costs the humans behind it time
    assert a["human_mean_time_loss_s"] > b["human_mean_time_loss_s"] + 2.0
    assert a["human_mean_travel_time_s"] > b["human_mean_travel_time_s"]


def test_demand_scale_thins_the_human_traffic(write_scenario, tmp_path):
    def humans(scale: float) -> int:
        scenario = {
            "simulation": {"step_s": 0.5, "end_s": 200.0, "seed": 5},
            "network": {"net_file": str(URBAN_GRID_NET)},
            "traffic": {"scale": scale, "flows": [{"from_edge": "left1A1", "to_edge": "C1right1",
                                                   "vehs_per_hour": 720, "end_s": 100.0}]},
        }  # fmt: skip
        plan = load_plan(write_scenario(scenario, f"scale_{scale}.yaml"))
        out = run(plan, tmp_path / f"scale_{scale}").directory
        return int(json.loads((out / "summary.json").read_text())["traffic"]["human_trips"])

    full, half = humans(1.0), humans(0.5)
    assert full == 20  # 720 veh/h for 100 s
    assert half == full // 2
