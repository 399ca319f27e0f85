"""Contacts in a real SUMO run name the vehicle at fault (platoon_sumo.fault): a human
driver ramming a platoon from behind is not the platoon's fault; a platoon car driving
into its predecessor is."""

from __future__ import annotations

import json
from pathlib import Path

import libsumo
import pandas as pd
import pytest

from platoon_sumo.loop.context import StepHook, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET

ROUTE = ["left1A1", "A1B1", "B1C1", "C1right1"]
PLUGINS = Path(__file__).resolve().parents[1] / "plugins"


class RamFromBehind(StepHook):
    """At `at_s`, a human-driven car enters the platoon's lane behind it at 14 m/s with
    every one of SUMO's safety checks off (speed mode 0), and keeps going."""

    rammer = "rammer"

    def __init__(self, at_s: float):
        self.at_s = at_s
        self.added = False

    def on_step(self, record: StepRecord) -> None:
        if self.added or record.time_s < self.at_s:
            return
        libsumo.route.add("ram_route", ROUTE)
        libsumo.vehicle.add(self.rammer, "ram_route", depart="now", departLane="0",
                            departPos="0", departSpeed="14")  # fmt: skip
        libsumo.vehicle.setSpeedMode(self.rammer, 0)
        libsumo.vehicle.setLaneChangeMode(self.rammer, 0)
        libsumo.vehicle.setSpeed(self.rammer, 14.0)
        self.added = True


def _events(out: Path) -> pd.DataFrame:
    events = pd.read_csv(out / "events.csv", keep_default_na=False)
    return events[events["kind"] == "collision"]


def test_a_human_driver_ramming_the_platoon_is_at_fault(write_scenario, tmp_path):
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 40.0, "seed": 3},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 2.0, "depart_lane": 0,
            "route": {"edges": ROUTE},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 4.0}},
        }],
    }  # fmt: skip
    ram = RamFromBehind(at_s=8.0)
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out", [ram]).directory
    collisions = _events(out)
    assert len(collisions) >= 1
    first = collisions.iloc[0]
    assert {first["vehicle_id"], first["other_id"]} == {"p.0", ram.rammer}
    assert first["at_fault"] == ram.rammer
    summary = json.loads((out / "summary.json").read_text())
    assert summary["collisions"] >= 1 and summary["collisions_platoon_at_fault"] == 0
    assert summary["collision_events"][0]["at_fault"] == ram.rammer
    vehicles = pd.read_csv(out / "vehicles.csv").set_index("vehicle_id")
    assert vehicles.loc["p.0", "collisions"] >= 1
    assert vehicles.loc["p.0", "collisions_at_fault"] == 0


def test_a_platoon_car_driving_into_its_predecessor_is_at_fault(
    write_scenario, tmp_path, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.syspath_prepend(str(PLUGINS))
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 20.0, "seed": 3},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{
            "id": "p", "members": 2, "spacing_m": 10.0, "depart_s": 1.0, "depart_lane": 0,
            "actuation": "planar",
            "route": {"edges": ROUTE},
            "supervisor": {"emergency_braking": False},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 3.0}},
            # blind and fast: drives straight on into the leader
            "follower": {"type": "my_controller:MyController",
                         "params": {"cruise_speed_mps": 8.0}},
        }],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    collisions = _events(out)
    assert len(collisions) >= 1
    first = collisions.iloc[0]
    assert {first["vehicle_id"], first["other_id"]} == {"p.0", "p.1"}
    assert first["at_fault"] == "p.1"
    assert first["detail"] == "front into the other's side or rear"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["collisions_platoon_at_fault"] == summary["collisions"] >= 1
    platoons = pd.read_csv(out / "platoons.csv").set_index("platoon_id")
    assert platoons.loc["p", "collisions_at_fault"] >= 1
