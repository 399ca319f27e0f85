"""Sublane actuation: SUMO drives the speed, our controllers' heading moves the car
sideways within and across lanes (SUMO's sublane model), and the car stays a SUMO
vehicle. On a straight two-lane road a weaving leader (`tests/plugins/weave.py`) steers
beside the lane centre, or into the next lane, and a laser follower follows it."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

STRAIGHT_NET = REPO / "networks" / "straight" / "straight.net.xml"
PLUGINS = REPO / "tests" / "plugins"


@pytest.fixture(autouse=True)
def plugins_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))


def weave(write_scenario, tmp_path, actuation: str, offset_m: float) -> pd.DataFrame:
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 60.0, "seed": 1, "lateral_resolution_m": 0.4},
        "network": {"net_file": str(STRAIGHT_NET)},
        "platoons": [{
            "id": "p", "members": 2, "spacing_m": 8.0, "depart_s": 1.0,
            "actuation": actuation, "route": {"edges": ["WE"]},
            "leader": {"type": "weave:Weave", "params": {"offset_m": offset_m}},
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                         "params": {"on_lost": "route_following", "corridor_margin_rel": 1.2}},
        }],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0
    return pd.read_csv(out / "trajectories.csv")


def last_seconds(traj: pd.DataFrame, vehicle: str, column: str, seconds: float = 10.0):
    rows = traj[traj["vehicle_id"] == vehicle]
    return rows.loc[rows["time_s"] > rows["time_s"].max() - seconds, column]


def test_follower_tracks_its_predecessors_offset_within_the_lane(write_scenario, tmp_path):
    traj = weave(write_scenario, tmp_path, "sublane", 0.8)
    for vid in ("p.0", "p.1"):
        assert (last_seconds(traj, vid, "lateral_offset_m") - 0.8).abs().max() < 0.2, vid
        assert (last_seconds(traj, vid, "lane_id") == "WE_0").all(), vid


def test_under_lane_actuation_sumo_keeps_the_lane_centre(write_scenario, tmp_path):
    traj = weave(write_scenario, tmp_path, "lane", 0.8)
    assert traj["lateral_offset_m"].abs().max() < 1e-6


def test_a_lane_change_decided_by_the_controller(write_scenario, tmp_path):
    # one edge to its end: nothing in the route asks SUMO for a change, and SUMO makes
    # none of its own under sublane actuation; the leader steers into the next lane
    traj = weave(write_scenario, tmp_path, "sublane", 3.5)
    for vid in ("p.0", "p.1"):
        assert (last_seconds(traj, vid, "lane_id") == "WE_1").all(), vid
        assert (last_seconds(traj, vid, "lateral_offset_m") - 3.5).abs().max() < 0.6, vid
    follower = traj[traj["vehicle_id"] == "p.1"]
    assert follower["predecessor_in_view"].mean() > 0.95


@pytest.mark.parametrize("actuation", ["sublane", "planar"])
def test_steered_actuation_needs_the_sublane_model(write_scenario, actuation):
    from platoon_sumo.errors import ScenarioError

    scenario = {
        "simulation": {"lateral_resolution_m": None},
        "network": {"net_file": str(STRAIGHT_NET)},
        "platoons": [{"id": "p", "route": {"edges": ["WE"]}, "actuation": actuation}],
    }
    with pytest.raises(ScenarioError, match=f"uses {actuation} actuation"):
        load_plan(write_scenario(scenario))
