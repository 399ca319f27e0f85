"""`actuation: lane`: SUMO drives the platoon cars along their lanes at our commanded speed.

The controllers and the supervisor decide the speed; SUMO keeps the lane, makes the
route's lane changes and applies its own safe speed, lights and right of way as the last
safety layer, so SUMO's drivers see the platoon exactly as one of their own.
"""

from __future__ import annotations

import json
from typing import Any

import pandas as pd
import pytest
import yaml

from platoon_sumo.runner import load_plan, run
from platoon_sumo.scenario import VehicleConfig
from platoon_sumo.vehicles import powertrain_speed
from tests.helpers import REPO, URBAN_GRID_NET
from tests.integration.test_urban_grid import signalised_junctions_crossed

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out


def _urban_platoon(**platoon_changes: Any) -> dict[str, Any]:
    scenario = yaml.safe_load((REPO / "scenarios" / "urban_platoon.yaml").read_text())
    scenario["network"]["net_file"] = str(URBAN_GRID_NET)
    del scenario["outputs"]
    platoon = scenario["platoons"][0]
    platoon["actuation"] = "lane"
    platoon["vehicle"]["sumo_tau_s"] = 0.5
    platoon.update(platoon_changes)
    return scenario


@pytest.fixture(scope="module")
def lane_platoon(tmp_path_factory: pytest.TempPathFactory):
    tmp = tmp_path_factory.mktemp("lane_platoon")
    path = tmp / "scenario.yaml"
    path.write_text(yaml.safe_dump(_urban_platoon()))
    plan = load_plan(path)
    out = run(plan, tmp / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    traj = pd.read_csv(out / "trajectories.csv")
    vehicle, dt_s = plan.platoons[0].config.vehicle, plan.scenario.simulation.step_s
    traj["sent_speed_mps"] = _speed_sent(traj, vehicle, dt_s)
    return summary, traj


def _speed_sent(traj: pd.DataFrame, vehicle: VehicleConfig, dt_s: float) -> pd.Series:
    """The speed handed to SUMO in each row: the executed command after the car's
    powertrain, from the vehicle's speed and acceleration in its previous row."""
    sent = traj["executed_speed_mps"].copy()
    for _, rows in traj.groupby("vehicle_id"):
        prev = rows.shift().dropna(subset=["speed_mps"])
        sent[prev.index] = powertrain_speed(
            prev["speed_mps"].to_numpy(), prev["accel_mps2"].to_numpy(),
            rows.loc[prev.index, "executed_speed_mps"].to_numpy(), vehicle.powertrain(),
            vehicle.limits(), dt_s,
        )  # fmt: skip
    return sent


def test_laser_platoon_driven_by_sumo_crosses_the_grid_safely(lane_platoon):
    summary, traj = lane_platoon
    assert summary["platoon_vehicles"]["arrived"] == 5
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0
    assert summary["red_light_violations"] == 0 and summary["teleports"] == 0
    for vid, rows in traj.groupby("vehicle_id"):
        assert len(signalised_junctions_crossed(rows["lane_id"])) >= 3, vid
        # SUMO keeps the car in its lane: the centre stays on the lane's centre-line
        assert (rows["lateral_offset_m"].abs() < 0.3).all(), vid


def test_sumo_only_ever_lowers_the_commanded_speed(lane_platoon):
    _, traj = lane_platoon
    # the speed reached in a step never exceeds what was sent: what the supervisor let
    # through, after the car's powertrain (its lag, within the acceleration limits)
    assert (traj["speed_mps"] <= traj["sent_speed_mps"] + 1e-6).all()
    # in free driving (nothing enforced) the speed sent is the speed, within SUMO's float
    # precision
    leader = traj[traj["vehicle_id"] == "cars.0"]
    free = leader[leader["supervisor"].isna() & leader["speed_mps"].shift().notna()]
    assert (free["speed_mps"] - free["sent_speed_mps"]).abs().max() < 0.01


def test_laser_followers_keep_their_predecessor_in_lane_actuation(lane_platoon):
    summary, _ = lane_platoon
    for vid, m in summary["followers"]["cars"].items():
        assert m["in_view_share"] > 0.95, vid
        assert m["min_gap_m"] > 1.0, vid
        assert m["rms_spacing_error_m"] < 2.5, vid


def test_sumo_stops_a_reckless_controller_at_red_lights_and_behind_cars(tmp_path, monkeypatch):
    # A controller that commands 13 m/s whatever happens, with our supervisor switched
    # off: in lane actuation SUMO's own rules still stop it at every red light and
    # behind every queue, and report how often they had to.
    monkeypatch.syspath_prepend(str(REPO / "tests" / "plugins"))
    reckless = {"type": "my_controller:MyController", "params": {"cruise_speed_mps": 13.0}}
    scenario = _urban_platoon(
        members=2,
        leader=reckless,
        follower=reckless,
        supervisor={"signals": False, "yield_at_junctions": False, "emergency_braking": False},
    )
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario))
    out = run(load_plan(path), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    traj = pd.read_csv(out / "trajectories.csv")
    assert summary["platoon_vehicles"]["arrived"] == 2
    assert summary["collisions"] == 0 and summary["red_light_violations"] == 0
    assert summary["sumo_speed_caps"] > 0
    held = traj[traj["supervisor"] == "sumo"]
    stopped_at_red = held[(held["signal_state"] == "r") & (held["speed_mps"] < 0.1)]
    assert len(stopped_at_red) > 0
    for vid, rows in traj.groupby("vehicle_id"):  # the first row precedes any command
        assert (rows["cmd_speed_mps"].iloc[1:] == 13.0).all(), vid
