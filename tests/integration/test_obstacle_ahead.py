"""A wide vehicle standing on the next lane reaches 0.4 m into the platoon cars' path
(SUMO, without its sublane model, does not see it as a leader): the platoon stops before
it and goes on once it has left (loop.obstacles); without the corridor check the platoon
hits it."""

from __future__ import annotations

import json

import libsumo
import pandas as pd
import pytest

import platoon_sumo.cosim as cosim
from platoon_sumo.loop.context import StepHook, StepRecord
from platoon_sumo.loop.obstacles import ObstaclesAhead
from platoon_sumo.runner import load_plan, run
from tests.helpers import add_standing_car, planar_pair_through_b1

BLOCKER = "blocker"
#: The blocker's front bumper on A1B1's left lane (centre y 298.4, nearer than the right
#: lane's 295.2, so SUMO keeps it there); 3 m wide, its right side is at y 295.7, 0.4 m
#: inside the path of the platoon cars' left sides (295.2 + 0.9).
FRONT_X, FRONT_Y, WIDTH_M = 200.0, 297.2, 3.0


class Blocker(StepHook):
    """A car standing at (FRONT_X, FRONT_Y) from `from_s` to `until_s`, then gone."""

    def __init__(self, from_s: float, until_s: float):
        self.from_s, self.until_s = from_s, until_s
        self.state = "waiting"

    def on_step(self, record: StepRecord) -> None:
        if self.state == "waiting" and record.time_s >= self.from_s:
            add_standing_car(BLOCKER, ["A1B1", "B1C1"], WIDTH_M, "1", "80")
            self.state = "standing"
        if self.state == "standing":
            if record.time_s >= self.until_s:
                libsumo.vehicle.remove(BLOCKER)
                self.state = "gone"
                return
            libsumo.vehicle.setSpeed(BLOCKER, 0.0)
            libsumo.vehicle.moveToXY(BLOCKER, "A1B1", 1, FRONT_X, FRONT_Y, 90.0, keepRoute=2)


def scenario() -> dict:
    return planar_pair_through_b1(depart_s=5.0, depart_lane=0, end_s=110.0)


def test_platoon_stops_before_a_car_reaching_into_its_lane(write_scenario, tmp_path):
    blocker = Blocker(from_s=6.0, until_s=30.0)
    out = run(load_plan(write_scenario(scenario())), tmp_path / "out", [blocker]).directory
    assert blocker.state == "gone"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["collisions"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 2
    traj = pd.read_csv(out / "trajectories.csv")
    leader = traj[traj["vehicle_id"] == "p.0"]
    waiting = leader[(leader["time_s"] > 25.0) & (leader["time_s"] < 30.0)]
    # it stood before the blocker's rear (front x 200, 5 m long) until it left
    assert waiting["speed_mps"].max() < 0.1
    assert 190.0 < waiting["x_m"].max() < 195.0


def test_without_the_corridor_check_the_platoon_hits_it(
    write_scenario, tmp_path, monkeypatch: pytest.MonkeyPatch
):
    stages = cosim.after_sumo_stages
    monkeypatch.setattr(
        cosim,
        "after_sumo_stages",
        lambda: [s for s in stages() if not isinstance(s, ObstaclesAhead)],
    )
    blocker = Blocker(from_s=6.0, until_s=30.0)
    out = run(load_plan(write_scenario(scenario())), tmp_path / "out", [blocker]).directory
    events = pd.read_csv(out / "events.csv", keep_default_na=False)
    hits = events[(events["kind"] == "collision") & (events["other_id"] == BLOCKER)]
    assert len(hits) >= 1 and hits.iloc[0]["at_fault"] == "p.0"
