"""A car turning left across the platoon's path starts into the junction and stops
inside it, across the platoon's lane (as SUMO's drivers do when they start and then
yield late, loop.obstacles.moving_footprints). The platoon sees it where it will be,
not only once its body is in the way."""

from __future__ import annotations

import json

import libsumo
import pandas as pd
import pytest

import platoon_sumo.loop.obstacles as obstacles
from platoon_sumo.loop.context import StepHook, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import add_standing_car, planar_pair_through_b1

TURNER = "turner"
#: The turner waits at the end of C1B1's left lane (westbound) and turns left into
#: B1B0 across A1B1 -> B1C1 (eastbound, the platoon's left lane): it starts for
#: `TURN_SPEED_MPS` when the platoon's leader passes `RELEASE_X` and brakes to a stop
#: when it is `STOP_AT_M` into the junction, where its first junction lane ends (it
#: stands across the platoon's lane 1.5 s later); it leaves after `STANDS_S`.
RELEASE_X, TURN_SPEED_MPS, STOP_AT_M, STANDS_S = 282.0, 7.0, 5.0, 8.0


class Turner(StepHook):
    """A car turning left that SUMO does not make yield (it obeys only TraCI)."""

    def __init__(self) -> None:
        self.state, self.stood_at = "absent", 0.0
        self.leader_x_m: list[tuple[float, float]] = []

    def on_step(self, record: StepRecord) -> None:
        veh = libsumo.vehicle
        if self.state == "absent" and record.time_s >= 1.0:
            length = libsumo.lane.getLength("C1B1_1")
            add_standing_car(TURNER, ["C1B1", "B1B0"], 1.8, "1", repr(length - 0.5))
            veh.setSpeedMode(TURNER, 0b00110)  # its own accel and decel, nothing else
            veh.setSpeed(TURNER, 0.0)
            self.state = "waiting"
        if "p.0" in veh.getIDList():
            self.leader_x_m.append((record.time_s, veh.getPosition("p.0")[0]))
        if self.state == "waiting" and self.leader_x_m and self.leader_x_m[-1][1] >= RELEASE_X:
            veh.setSpeed(TURNER, TURN_SPEED_MPS)
            self.state = "turning"
        elif self.state == "turning" and veh.getLaneID(TURNER) in (":B1_7_0", ":B1_17_0"):
            into = veh.getLanePosition(TURNER)
            if veh.getLaneID(TURNER) == ":B1_17_0":
                into += libsumo.lane.getLength(":B1_7_0")
            if into >= STOP_AT_M:
                veh.setSpeed(TURNER, 0.0)
                self.state, self.stood_at = "stopping", record.time_s
        elif self.state == "stopping" and record.time_s >= self.stood_at + STANDS_S:
            veh.remove(TURNER)
            self.state = "gone"


def scenario() -> dict:
    return planar_pair_through_b1(depart_s=35.0, depart_lane=1, end_s=170.0)


def crossing_run(write_scenario, tmp_path) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    turner = Turner()
    out = run(load_plan(write_scenario(scenario())), tmp_path / "out", [turner]).directory
    assert turner.state == "gone"
    summary = json.loads((out / "summary.json").read_text())
    events = pd.read_csv(out / "events.csv", keep_default_na=False)
    traj = pd.read_csv(out / "trajectories.csv")
    return summary, events, traj[traj["vehicle_id"] == "p.0"]


def test_a_car_stopping_across_the_path_is_seen_before_it_is_there(write_scenario, tmp_path):
    summary, _, leader = crossing_run(write_scenario, tmp_path)
    assert summary["collisions"] == 0 and summary["emergency_brakings"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 2
    # the leader stood before the turner's path (it crosses the lane at x 301-305)
    stood = leader[(leader["time_s"] > 50.0) & (leader["speed_mps"] < 0.05)]
    assert 295.0 < stood["x_m"].min() < 300.0


def test_seen_only_once_in_the_way_the_leader_hits_it(
    write_scenario, tmp_path, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setattr(obstacles, "AHEAD_S", 0.0)  # seen where it is
    _, events, _ = crossing_run(write_scenario, tmp_path)
    hits = events[(events["kind"] == "collision") & (events["other_id"] == TURNER)]
    assert len(hits) >= 1 and hits.iloc[0]["vehicle_id"] == "p.0"
