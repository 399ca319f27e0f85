"""Issue acceptance: the paper's five-robot laser-only platoon, reproduced in SUMO."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from platoon_sumo.sumo.network import Network
from tests.helpers import PAPER_WORLD, REPO

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out

LOOP = ["SW_S", "S_SE", "SE_NE", "NE_N", "N_NW", "NW_SW"]


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("paper_world")
    run(load_plan(REPO / "scenarios" / "paper_world.yaml"), out_dir=out)
    return out


def test_platoon_keeps_formation_over_a_full_lap_without_collisions(paper_run):
    summary = json.loads((paper_run / "summary.json").read_text())
    traj = pd.read_csv(paper_run / "trajectories.csv")
    lap_m = Network(PAPER_WORLD / "paper_world.net.xml").route_path(LOOP, 0.02, 0).length_m
    # every robot, the last one included, drove at least one full lap (four corner turns)
    assert traj.groupby("vehicle_id")["route_s_m"].max().min() > lap_m
    assert summary["collisions"] == 0  # with each other, with walls and with any vehicle
    assert summary["emergency_brakings"] == 0  # the laser-only algorithms did it alone
    followers = summary["followers"]["robots"]
    assert sorted(followers) == ["robots.1", "robots.2", "robots.3", "robots.4"]
    for vid, m in followers.items():
        # the predecessor is in the follower's scan at every scan, from its first
        assert m["in_view_share"] == 1.0 and m["lost_scans"] == 0, vid
        assert m["min_gap_m"] >= 0.3, vid  # never inside the scanner's minimum range


def test_leader_stays_in_its_right_lane(paper_run):
    traj = pd.read_csv(paper_run / "trajectories.csv")
    leader = traj[traj["role"] == "leader"]
    assert (leader["lateral_offset_m"].abs() < leader["lane_width_m"] / 2).all()
    normal_lanes = leader.loc[~leader["lane_id"].str.startswith(":"), "lane_id"]
    assert normal_lanes.str.endswith("_0").all()  # lane 0 is the right lane
