"""A platoon turns left on a permissive green (``g``) through the gaps of oncoming
traffic (lane actuation: SUMO's gap acceptance for the real approach underneath; the
supervisor does not also hold the vehicle at the minor link)."""

from __future__ import annotations

import json

import libsumo
import pandas as pd

from platoon_sumo.loop.context import StepHook, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET


class OncomingTimes(StepHook):
    """When each oncoming car reached the far side of the junction (edge A1left1)."""

    def __init__(self) -> None:
        self.first_seen: dict[str, float] = {}

    def on_step(self, record: StepRecord) -> None:
        for vid in libsumo.edge.getLastStepVehicleIDs("A1left1"):
            self.first_seen.setdefault(vid, record.time_s)


def test_platoon_turns_left_through_gaps_in_oncoming_traffic(write_scenario, tmp_path):
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 150.0, "seed": 2},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "traffic": {"flows": [{"from_edge": "B1A1", "to_edge": "A1left1",
                               "vehs_per_hour": 500, "begin_s": 0.0, "end_s": 150.0}]},
        "platoons": [{
            "id": "p", "members": 3, "spacing_m": 8.0, "depart_s": 20.0, "actuation": "lane",
            "route": {"edges": ["left1A1", "A1A2", "A2top0"]},  # left at A1, green is "g"
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                         "params": {"on_lost": "route_following"}},
        }],
    }  # fmt: skip
    oncoming = OncomingTimes()
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out", [oncoming]).directory
    summary = json.loads((out / "summary.json").read_text())
    assert summary["platoon_vehicles"]["arrived"] == 3
    assert summary["collisions"] == 0 and summary["red_light_violations"] == 0
    assert summary["sumo_collisions"] == 0
    traj = pd.read_csv(out / "trajectories.csv")
    assert (traj["supervisor"] != "yield").all()
    leader = traj[traj["vehicle_id"] == "p.0"]
    approach = leader[leader["lane_id"].str.startswith("left1A1")]
    assert approach["signal_state"].iloc[-1] == "g"  # entered on the permissive green
    turned_s = leader.loc[leader["lane_id"].str.startswith("A1A2"), "time_s"].min()
    # oncoming cars crossed shortly before and after: the turn took a gap in the flow
    times = pd.Series(oncoming.first_seen)
    assert ((times > turned_s - 8.0) & (times < turned_s)).any()
    assert ((times > turned_s) & (times < turned_s + 8.0)).any()
