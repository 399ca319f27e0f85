"""Sublane actuation: an oncoming car standing inside a junction with its side 0.15 m in
the platoon's way (as SUMO's cars wait where a network's internal lanes overlap: on the
unrepaired DRT district a car waiting to merge stood with its corner in a follower's
way, each waiting for the other) is passed by a sidestep within the lane, without
contact; without the sidestep the platoon waits before it for good
(loop.obstacles.sidestep_clearing)."""

from __future__ import annotations

import json

import libsumo
import pandas as pd
import pytest

from platoon_sumo.loop import obstacles
from platoon_sumo.loop.context import StepHook, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET, add_standing_car

BLOCKER = "blocker"
#: The blocker: 3 m wide, facing west inside junction B1 (x 289.6 to 310.4) on the
#: westbound inner lane (centre y 301.6; so for SUMO it is neither the platoon's leader
#: nor a foe at the junction), 0.95 m off its centre towards the eastbound lanes. The
#: platoon drives the eastbound inner lane's centre, y 298.4, its cars' left sides at
#: 299.3; the blocker's side is at 299.15.
FRONT_X, CENTRE_Y, WIDTH_M = 298.0, 300.65, 3.0


class Blocker(StepHook):
    """A car standing at (FRONT_X, CENTRE_Y) from `from_s` to the end of the run."""

    def __init__(self, from_s: float):
        self.from_s = from_s
        self.placed = False

    def on_step(self, record: StepRecord) -> None:
        if record.time_s < self.from_s:
            return
        if not self.placed:
            add_standing_car(BLOCKER, ["C1B1", "B1A1"], WIDTH_M, "1", "150")
            self.placed = True
        libsumo.vehicle.setSpeed(BLOCKER, 0.0)
        libsumo.vehicle.moveToXY(BLOCKER, "", -1, FRONT_X, CENTRE_Y, 270.0, keepRoute=2)


def scenario() -> dict:
    return {
        "simulation": {"step_s": 0.1, "end_s": 90.0, "seed": 1, "lateral_resolution_m": 0.8},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{
            "id": "p", "members": 3, "spacing_m": 10.0, "depart_s": 5.0, "depart_lane": 1,
            "actuation": "sublane", "route": {"edges": ["A1B1", "B1C1", "C1right1"]},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 8.0}},
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                         "params": {"on_lost": "route_following"}},
        }],
    }  # fmt: skip


def run_with_blocker(write_scenario, tmp_path) -> tuple[dict, pd.DataFrame, Blocker]:
    blocker = Blocker(from_s=2.0)
    out = run(load_plan(write_scenario(scenario())), tmp_path / "out", [blocker]).directory
    summary = json.loads((out / "summary.json").read_text())
    return summary, pd.read_csv(out / "trajectories.csv"), blocker


def test_a_platoon_sidesteps_a_car_standing_in_its_way_in_a_junction(write_scenario, tmp_path):
    summary, traj, blocker = run_with_blocker(write_scenario, tmp_path)
    assert blocker.placed
    assert summary["collisions"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 3
    # every member passed the blocker to its right, within its lane (half width 1.6 m)
    passing = traj[(traj["x_m"] > FRONT_X) & (traj["x_m"] < FRONT_X + 5.0)]
    offsets = passing.groupby("vehicle_id")["lateral_offset_m"].min()
    assert set(offsets.index) == {"p.0", "p.1", "p.2"}
    assert (offsets < -0.15).all() and (offsets > -0.7).all()


def test_without_the_sidestep_the_platoon_waits_for_good(
    write_scenario, tmp_path, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setattr(obstacles, "sidestep_clearing", lambda *args: 0.0)
    summary, traj, _ = run_with_blocker(write_scenario, tmp_path)
    assert summary["collisions"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 0
    leader = traj[traj["vehicle_id"] == "p.0"]
    assert leader["x_m"].max() < FRONT_X
