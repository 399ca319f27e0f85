"""Issue acceptance: a car-scale laser-only platoon through the signalised urban grid."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO
from tests.integration.test_urban_grid import TrafficAroundEgo, signalised_junctions_crossed

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out


@pytest.fixture(scope="module")
def platoon_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, TrafficAroundEgo]:
    out = tmp_path_factory.mktemp("urban_platoon")
    counter = TrafficAroundEgo()
    run(load_plan(REPO / "scenarios" / "urban_platoon.yaml"), out_dir=out, hooks=[counter])
    return out, counter


def test_platoon_of_five_crosses_signals_and_turns_safely(platoon_run):
    out, counter = platoon_run
    summary = json.loads((out / "summary.json").read_text())
    traj = pd.read_csv(out / "trajectories.csv")
    assert summary["platoon_vehicles"]["arrived"] == summary["platoon_vehicles"]["planned"] == 5
    assert summary["collisions"] == 0
    assert summary["red_light_violations"] == 0
    assert summary["teleports"] == 0
    assert counter.max_sumo_vehicles_while_active >= 100
    assert counter.count_mismatches == []  # also after the platoon's arrivals
    for vid, rows in traj.groupby("vehicle_id"):
        assert len(signalised_junctions_crossed(rows["lane_id"])) >= 3, vid
        # two right turns: the heading changes by about 90 degrees twice
        assert rows["yaw_rad"].max() - rows["yaw_rad"].min() > 2.5, vid


def test_followers_keep_spacing_and_the_leaders_line(platoon_run):
    out, _ = platoon_run
    followers = json.loads((out / "summary.json").read_text())["followers"]["cars"]
    assert sorted(followers) == ["cars.1", "cars.2", "cars.3", "cars.4"]
    for vid, m in followers.items():
        assert m["in_view_share"] == 1.0, vid  # laser-only: the predecessor never lost
        assert m["min_gap_m"] > 1.0, vid
        assert m["rms_spacing_error_m"] < 2.0, vid
        assert m["max_lateral_deviation_m"] < 1.6, vid  # half a 3.2 m lane
        assert m["rms_lateral_deviation_m"] < 0.3, vid


def test_followers_with_a_noisy_dropping_laser_bring_the_platoon_through(tmp_path):
    """The shipped noisy-laser scenario (30 mm range noise, 1 % of returns lost) runs
    to completion with the same safety as the clean one."""
    plan = load_plan(REPO / "scenarios" / "urban_platoon_noisy.yaml")
    laser = plan.platoons[0].members[1].laser
    assert laser is not None and laser.noise_std_m == 0.03 and laser.dropout_prob == 0.01
    run(plan, out_dir=tmp_path / "noisy")
    summary = json.loads((tmp_path / "noisy" / "summary.json").read_text())
    assert summary["status"] == "complete"
    assert summary["platoon_vehicles"]["arrived"] == 5
    assert summary["collisions"] == 0 and summary["red_light_violations"] == 0
    for vid, m in summary["followers"]["cars"].items():
        assert m["in_view_share"] > 0.95, vid
        assert m["min_gap_m"] > 1.0, vid
