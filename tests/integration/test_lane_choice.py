"""Lane actuation: who chooses a lane-actuated car's lane. The controller may keep its
lane against SUMO's strategic lane change (a laser follower keeps its predecessor's
lane), but only while the route can still be followed from there: on a three-lane
approach whose left lane alone turns left (tests/integration/test_sublane_actuation.py's
network), a car asking to keep lane 0 all the way is moved over by SUMO in time for
its turn, later than SUMO alone would move it; without the reserve
(`LANE_CHOICE_RESERVE_*` set to 0) the hold would keep it at the end of lane 0 for good."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from platoon_sumo.sumo import backend
from tests.helpers import REPO, build_net
from tests.integration.test_sublane_actuation import CONNECTIONS, EDGES, NODES

APPROACH_M = 200.0
"""Length of W-C, the approach to the left turn."""


@pytest.fixture(autouse=True)
def plugins_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(REPO / "tests" / "plugins"))


@pytest.fixture(scope="module")
def left_turn_lane(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_net(tmp_path_factory.mktemp("lane_choice"), NODES, EDGES, CONNECTIONS)


def drive(write_scenario, tmp_path, net: Path, keep: bool) -> tuple[dict, pd.DataFrame]:
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 60.0, "seed": 1},
        "network": {"net_file": str(net)},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 1.0, "depart_lane": 0,
            "actuation": "lane", "route": {"edges": ["WC", "CN"]},
            "leader": {"type": "lane_keeper:LaneKeeper", "params": {"keep": keep}},
        }],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    return summary, pd.read_csv(out / "trajectories.csv")


def first_route_s_on(traj: pd.DataFrame, lane: str) -> float:
    return float(traj.loc[traj["lane_id"] == lane, "route_s_m"].min())


def test_a_kept_lane_holds_until_the_route_needs_the_change(
    left_turn_lane, write_scenario, tmp_path
):
    summary, kept = drive(write_scenario, tmp_path / "kept", left_turn_lane, keep=True)
    _, free = drive(write_scenario, tmp_path / "free", left_turn_lane, keep=False)
    assert summary["collisions"] == 0
    for traj in (kept, free):
        assert traj["lane_id"].iloc[-1] == "CN_0"  # turned left: the route is kept
    # two lane changes still needed from lane 0: held until about two reserves before
    # the lanes end (8 m/s: 50 m each), where SUMO alone moves over from the start
    reserve_m = max(backend.LANE_CHOICE_RESERVE_M, backend.LANE_CHOICE_RESERVE_S * 8.0)
    assert first_route_s_on(kept, "WC_1") > APPROACH_M - 2 * reserve_m - 10.0
    assert first_route_s_on(free, "WC_1") < first_route_s_on(kept, "WC_1") - 20.0


def test_without_the_reserve_the_hold_would_lose_the_route(
    left_turn_lane, write_scenario, tmp_path, monkeypatch
):
    monkeypatch.setattr(backend, "LANE_CHOICE_RESERVE_S", 0.0)
    monkeypatch.setattr(backend, "LANE_CHOICE_RESERVE_M", 0.0)
    _, traj = drive(write_scenario, tmp_path, left_turn_lane, keep=True)
    assert traj["lane_id"].iloc[-1] == "WC_0"
    assert traj["speed_mps"].iloc[-1] < 0.1
