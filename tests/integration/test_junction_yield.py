"""A platoon vehicle on a minor road yields to SUMO cars with priority."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from tests.helpers import build_net

NODES = """<nodes>
  <node id="W" x="-300" y="0"/> <node id="E" x="300" y="0"/>
  <node id="S" x="0" y="-300"/> <node id="N" x="0" y="300"/>
  <node id="C" x="0" y="0" type="priority"/>
</nodes>"""
EDGES = """<edges>
  <edge id="WC" from="W" to="C" priority="3" numLanes="1" speed="13.89"/>
  <edge id="CE" from="C" to="E" priority="3" numLanes="1" speed="13.89"/>
  <edge id="SC" from="S" to="C" priority="1" numLanes="1" speed="13.89"/>
  <edge id="CN" from="C" to="N" priority="1" numLanes="1" speed="13.89"/>
</edges>"""


@pytest.fixture(scope="module")
def priority_crossing(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An unsignalised crossing: main road W-E has priority over the minor road S-N."""
    d = tmp_path_factory.mktemp("crossing")
    return build_net(d, NODES, EDGES, None, "--no-turnarounds")


def test_platoon_vehicle_yields_to_priority_traffic(priority_crossing, write_scenario, tmp_path):
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 90.0, "seed": 1},
        "network": {"net_file": str(priority_crossing)},
        "traffic": {
            "vehicle_types": [{"id": "h", "sigma": 0.0}],
            "flows": [{"from_edge": "WC", "to_edge": "CE", "vehs_per_hour": 2400,
                       "begin_s": 0.0, "end_s": 50.0, "type": "h"}],
        },
        # planar: the supervisor's yield (with lane or sublane actuation SUMO gives way)
        "platoons": [{"id": "ego", "route": {"edges": ["SC", "CN"]}, "depart_s": 5.0,
                      "actuation": "planar"}],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    summary = (out / "summary.json").read_text()
    traj = pd.read_csv(out / "trajectories.csv")
    trips = pd.read_csv(out / "tripinfo.csv", sep=";")

    assert '"collisions": 0' in summary
    waiting = traj[(traj["supervisor"] == "yield") & (traj["speed_mps"] < 0.01)]
    assert len(waiting) > 20, "the ego stopped and waited at the minor approach"
    assert waiting["lane_id"].eq("SC_0").all()
    entered_s = traj.loc[traj["lane_id"].str.startswith(":C"), "time_s"].min()
    # While it waited, SUMO cars with priority crossed the junction in front of it.
    passed = trips[(trips["tripinfo_depart"] < entered_s - 15) & (trips["tripinfo_id"] != "ego.0")]
    assert len(passed) >= 3
    assert trips.loc[trips["tripinfo_id"] == "ego.0", "tripinfo_arrival"].notna().all()
    # and no SUMO driver had to brake hard because of the platoon vehicle
    safety = ET.parse(out / "sumo_statistics.xml").getroot().find("safety")
    assert safety is not None and safety.get("emergencyBraking") == "0"


def test_two_platoons_meeting_at_a_junction_pass_without_contact(
    priority_crossing, write_scenario, tmp_path
):
    """Two lane-actuated platoons reach the unsignalised crossing together, one on the
    main road, one on the minor road: the minor one gives way, nobody touches."""
    follower = {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                "params": {"on_lost": "route_following"}}  # fmt: skip
    platoon = {"members": 3, "spacing_m": 8.0, "actuation": "lane", "follower": follower}
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 90.0, "seed": 1},
        "network": {"net_file": str(priority_crossing)},
        "platoons": [
            {**platoon, "id": "main", "route": {"edges": ["WC", "CE"]}, "depart_s": 2.0},
            {**platoon, "id": "minor", "route": {"edges": ["SC", "CN"]}, "depart_s": 2.0},
        ],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 6
    traj = pd.read_csv(out / "trajectories.csv")
    entered = traj[traj["lane_id"].str.startswith(":C")].groupby("platoon_id")["time_s"]
    # they met: the minor platoon was still waiting when the main one entered the crossing
    minor = traj[traj["platoon_id"] == "minor"]
    first_main = entered.min()["main"]
    at_first_main = minor[(minor["time_s"] - first_main).abs() < 0.05]
    assert (at_first_main["lane_id"] == "SC_0").all() and len(at_first_main) == 3
    # and gave way: its first car stood at the end of the minor road
    leader = minor[minor["vehicle_id"] == "minor.0"]
    assert ((leader["speed_mps"] < 0.1) & (leader["lane_id"] == "SC_0")).sum() > 5
