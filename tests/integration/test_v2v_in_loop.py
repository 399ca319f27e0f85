"""The V2V channel in a real SUMO run: a 3-car platoon on the straight road whose
followers keep their gap from their predecessor's beacons alone (`v2v_follower` plug-in),
and the channel's counts in vehicles.csv, platoons.csv and summary.json."""

from __future__ import annotations

import importlib
import json
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

PLUGINS = Path(__file__).resolve().parents[1] / "plugins"
STRAIGHT = REPO / "networks" / "straight" / "straight.net.xml"
END_S = 12.0


def scenario(v2v: dict[str, Any]) -> dict[str, Any]:
    sensors = [{"type": "v2v", "params": v2v}]
    return {
        "simulation": {"step_s": 0.1, "end_s": END_S, "seed": 7},
        "network": {"net_file": str(STRAIGHT)},
        "platoons": [{
            "id": "p", "members": 3, "spacing_m": 10.0, "depart_pos_m": 60.0,
            "route": {"edges": ["WE"]},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 10.0},
                       "sensors": sensors},
            "follower": {"type": "v2v_follower:V2VFollower", "sensors": sensors},
        }],
    }  # fmt: skip


@pytest.fixture
def follower(monkeypatch: pytest.MonkeyPatch) -> Any:
    """The plug-in controller class the run loads (its `seen` emptied)."""
    monkeypatch.syspath_prepend(str(PLUGINS))
    cls = importlib.import_module("v2v_follower").V2VFollower
    cls.seen.clear()
    return cls


def test_followers_hear_their_predecessor_at_every_step(write_scenario, tmp_path, follower):
    out = run(load_plan(write_scenario(scenario({}))), tmp_path / "out").directory
    seen = follower.seen
    assert {s.vehicle_id for s in seen} == {"p.1", "p.2"}
    for s in seen:  # no delay: the predecessor's state of this very step
        assert s.predecessor is not None
        assert s.predecessor.sender_id == f"p.{int(s.vehicle_id[2:]) - 1}"
        assert s.predecessor.sent_s == pytest.approx(s.time_s)
        others = {"p.0", "p.1", "p.2"} - {s.vehicle_id}
        assert s.inbox is not None and set(s.inbox.latest) == others
    vehicles = pd.read_csv(out / "vehicles.csv").set_index("vehicle_id")
    sent = vehicles["v2v_sent"]
    # 10 Hz beacons at 0.1 s steps, from the step after the one SUMO inserted the car in
    assert (sent == vehicles["steps"] - 1).all()
    assert (vehicles["v2v_received"] == 2 * sent).all()  # from both others
    assert (vehicles["v2v_lost"] == 0).all()
    assert vehicles["min_gap_m"].dropna().min() > 5.0  # V2V alone kept the gaps
    platoon = pd.read_csv(out / "platoons.csv").set_index("platoon_id").loc["p"]
    assert platoon["v2v_sent"] == sent.sum()
    overall = json.loads((out / "summary.json").read_text())["overall"]
    assert overall["v2v_received"] == vehicles["v2v_received"].sum()
    assert overall["v2v_lost"] == 0


def test_delay_and_loss_reach_the_controllers_and_the_counts(write_scenario, tmp_path, follower):
    v2v = {"delay_s": 0.3, "loss_probability": 0.2}
    out = run(load_plan(write_scenario(scenario(v2v))), tmp_path / "out").directory
    ages = [round(s.time_s - s.predecessor.sent_s, 6) for s in follower.seen if s.predecessor]
    assert min(ages) == 0.3  # never fresher than the delay
    assert ages.count(0.3) > 0.7 * len(ages)  # mostly the latest beacon; older after a loss
    vehicles = pd.read_csv(out / "vehicles.csv").set_index("vehicle_id")
    addressed = vehicles["v2v_received"] + vehicles["v2v_lost"]
    assert (vehicles["v2v_lost"] > 0).all()
    assert 0.1 < vehicles["v2v_lost"].sum() / addressed.sum() < 0.3
    # messages of the last 0.3 s are still on the air when the run ends
    assert (addressed == 2 * (vehicles["v2v_sent"] - 3)).all()
