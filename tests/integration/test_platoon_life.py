"""Platoons in traffic: a red light splits a platoon that then re-forms; a SUMO car cuts in."""

from __future__ import annotations

import json

import libsumo
import pandas as pd
import pytest

from platoon_sumo.loop.context import RunContext, RunOutcome, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET


def test_red_light_splits_the_platoon_and_it_reforms_after_green(write_scenario, tmp_path):
    # The leader passes A1 on the last green; the light turns yellow for the first follower,
    # which stops, loses its predecessor, drives on at green and catches up again.
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 330.0, "seed": 3},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{
            "id": "p", "members": 3, "spacing_m": 10.0, "depart_s": 77.0,
            "route": {"edges": ["left1A1", "A1B1", "B1C1", "C1C2", "C2top2"]},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 7.0},
                       "sensor": {"preset": "utm30lx"}},
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                         "params": {"on_lost": "route_following",
                                    "fallback": {"cruise_speed_mps": 13.0}}},
        }],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    traj = pd.read_csv(out / "trajectories.csv")
    assert summary["collisions"] == 0 and summary["red_light_violations"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 3
    log = summary["platoon_event_log"]
    split = next(e for e in log if e["kind"] == "split")
    reform = next(e for e in log if e["kind"] == "reformation")
    assert split["follower_id"] == reform["follower_id"] and split["time_s"] < reform["time_s"]
    follower = traj[traj["vehicle_id"] == split["follower_id"]]
    # it was held by the red light while split ...
    between = (follower["time_s"] > split["time_s"]) & (follower["time_s"] < reform["time_s"])
    held = follower[between]
    at_red = held[(held["signal_state"] == "r") & (held["speed_mps"] < 0.01)]
    assert len(at_red) > 50
    # ... and re-formed only after that light had turned green
    assert at_red["time_s"].max() < reform["time_s"]
    assert summary["platoon_events"] == {"splits": 1, "reformations": 1, "cut_ins": 0}


class ForceCutIn:
    """Makes one SUMO car on the left lane change into the platoon's lane at a set time."""

    def __init__(self, at_s: float):
        self.at_s = at_s
        self.intruder: str | None = None

    def on_start(self, run: RunContext) -> None:
        pass

    def on_end(self, outcome: RunOutcome) -> None:
        pass

    def on_step(self, record: StepRecord) -> None:
        if self.intruder is not None or record.time_s < self.at_s:
            return
        w = record.world
        lead, follow = w.index.get("p.0"), w.index.get("p.1")
        if lead is None or follow is None:
            return
        gap_lo, gap_hi = w.front_x_m[follow], w.front_x_m[lead] - w.length_m[lead]
        for vid, i in w.index.items():  # a car on the left lane alongside the gap
            # its 5 m body fits in the gap with room to spare on both sides
            alongside = gap_lo + 8.0 < w.front_x_m[i] < gap_hi - 5.0
            left_lane = w.lane_ids[i] in ("left1A1_1", "A1B1_1")
            if not vid.startswith("p.") and left_lane and alongside:
                # An aggressive driver: only avoids an immediate collision (lcMode bits 8-9 = 1).
                libsumo.vehicle.setLaneChangeMode(vid, 0b01_0000_0000)
                libsumo.vehicle.changeLane(vid, 0, 5.0)
                self.intruder = vid
                return


def test_sumo_car_cuts_in_and_the_follower_opens_its_gap(write_scenario, tmp_path):
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 75.0, "seed": 5},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "traffic": {
            # faster than the platoon: they overtake it on the left lane
            "vehicle_types": [{"id": "h", "sigma": 0.0, "max_speed_mps": 10.0}],
            "flows": [{"from_edge": "left1A1", "to_edge": "C1right1", "vehs_per_hour": 1500,
                       "begin_s": 46.0, "end_s": 60.0, "type": "h"}],
        },
        "platoons": [{
            "id": "p", "members": 2, "spacing_m": 20.0, "depart_s": 45.0, "depart_lane": 0,
            "route": {"edges": ["left1A1", "A1B1", "B1C1", "C1right1"]},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 8.0},
                       "sensor": {"preset": "utm30lx"}},
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                         "params": {"time_gap_s": 2.5}},
        }],
    }  # fmt: skip
    forcing = ForceCutIn(at_s=46.0)
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out", [forcing]).directory
    summary = json.loads((out / "summary.json").read_text())
    assert forcing.intruder is not None, "a car was alongside the gap to cut in"
    cut_ins = [e for e in summary["platoon_event_log"] if e["kind"] == "cut_in"]
    assert [e["other_id"] for e in cut_ins] == [forcing.intruder]
    assert summary["collisions"] == 0
    traj = pd.read_csv(out / "trajectories.csv")
    follower = traj[(traj["vehicle_id"] == "p.1") & (traj["time_s"] >= cut_ins[0]["time_s"])]
    behind_intruder = follower[follower["ahead_id"] == forcing.intruder]
    assert len(behind_intruder) > 20
    # the follower opened a safe gap to the car that cut in (it never tailgated it)
    assert behind_intruder["ahead_gap_m"].min() > 2.0
    assert behind_intruder["ahead_gap_m"].iloc[-1] > behind_intruder["ahead_gap_m"].iloc[0]


def test_platoons_on_one_route_are_inserted_whole_when_there_is_room(write_scenario, tmp_path):
    route = {"edges": ["left1A1", "A1B1", "B1C1", "C1right1"]}
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 40.0, "seed": 2},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [
            {"id": "p", "members": 3, "spacing_m": 8.0, "depart_s": 2.0, "route": route},
            {"id": "q", "members": 3, "spacing_m": 8.0, "depart_s": 2.0, "route": route},
            {"id": "late", "members": 2, "depart_s": 39.95, "route": route},
        ],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    traj = pd.read_csv(out / "trajectories.csv")
    first_seen = traj.groupby("vehicle_id")["time_s"].min()
    # q waited until p had cleared the first lane, then all of q came in together
    assert first_seen[["q.0", "q.1", "q.2"]].min() > first_seen[["p.0", "p.1", "p.2"]].max() + 1.0
    assert first_seen[["q.0", "q.1", "q.2"]].nunique() == 1
    assert summary["collisions"] == 0
    assert summary["platoons_not_inserted"] == ["late"]


@pytest.mark.slow
def test_platoon_share_turns_part_of_a_flow_into_platoons(write_scenario, tmp_path):
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 300.0, "seed": 4},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "traffic": {"flows": [{"from_edge": "left1A1", "to_edge": "C1right1",
                               "vehs_per_hour": 480, "platoon_share": 0.25,
                               "platoon_template": "convoy"}]},
        "platoons": [{"id": "convoy", "template": True, "members": 3, "spacing_m": 8.0,
                      "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"}}}],
    }  # fmt: skip
    plan = load_plan(write_scenario(scenario))
    # 480 veh/h x 25 % = 120 platoon vehicles/h = 40 platoons of 3 an hour: one every 90 s
    assert [p.config.id for p in plan.platoons] == ["convoy_f0_0", "convoy_f0_1", "convoy_f0_2"]
    assert plan.platoons[1].config.depart_s - plan.platoons[0].config.depart_s == 90.0
    out = run(plan, tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    trips = pd.read_csv(out / "tripinfo.csv", sep=";")
    humans = trips[trips["tripinfo_id"].str.startswith("flow0")]
    assert 25 <= len(humans) <= 32  # the remaining 75 %: 360 veh/h for 300 s = 30
    assert summary["platoon_vehicles"]["departed"] == 9
    assert summary["collisions"] == 0


def test_lane_change_waits_for_a_gap_in_the_target_lane(write_scenario, tmp_path):
    # The route turns left at B0: the car must move to A0B0's left lane, which a flow of
    # left-turning SUMO cars keeps busy.
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 200.0, "seed": 8},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "traffic": {"flows": [{"from_edge": "left0A0", "to_edge": "B0B1", "vehs_per_hour": 2400,
                               "begin_s": 40.0, "end_s": 100.0}]},
        "platoons": [{"id": "ego", "depart_s": 50.0, "depart_lane": 0,
                      "route": {"edges": ["left0A0", "A0B0", "B0B1", "B1B2"]}}],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    traj = pd.read_csv(out / "trajectories.csv")
    assert summary["collisions"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 1
    assert (traj["supervisor"] == "merge").sum() > 5  # it had to wait for a gap
    assert "A0B0_1" in set(traj["lane_id"])  # and then changed lanes


@pytest.mark.slow
def test_platoon_longer_than_its_first_edge_departs_member_by_member(write_scenario, tmp_path):
    # 12 cars of 4.5 m with 8 m gaps need 142 m; the first edge is 89.6 m: 7 fit
    route = {"edges": ["left1A1", "A1B1", "B1C1", "C1right1"]}
    scenario = {
        # 200 s: with the cars' default (sublane) actuation the members that depart late
        # stand at red lights at A1 and C1, and the last one arrives after 150 s
        "simulation": {"step_s": 0.1, "end_s": 200.0, "seed": 5},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{
            "id": "long", "members": 12, "spacing_m": 8.0, "depart_s": 2.0, "route": route,
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                         "params": {"on_lost": "route_following"}},
        }],
    }  # fmt: skip
    plan = load_plan(write_scenario(scenario))
    waits = [m.waits_for_room for m in plan.platoons[0].members]
    assert waits == [False] * 7 + [True] * 5
    out = run(plan, tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    traj = pd.read_csv(out / "trajectories.csv")
    assert summary["platoon_vehicles"]["departed"] == 12
    assert summary["platoon_vehicles"]["arrived"] == 12
    assert summary["collisions"] == 0 and summary["red_light_violations"] == 0
    assert summary["members_not_inserted"] == [] and summary["platoons_not_inserted"] == []
    ids = [f"long.{k}" for k in range(12)]
    first_seen = traj.groupby("vehicle_id")["time_s"].min()[ids]
    assert first_seen.iloc[:7].nunique() == 1  # the members that fit came in together
    # the others one by one, in order, each after the one ahead of it
    assert (first_seen.diff().iloc[7:] > 0).all()
    # each entered with at least the platoon's spacing to the member ahead
    entry = traj.loc[traj.groupby("vehicle_id")["time_s"].idxmin()].set_index("vehicle_id")
    assert (entry.loc[ids[7:], "gap_to_predecessor_m"] >= 8.0 - 0.5).all()
    # and followed it: the laser saw its predecessor most of the way
    followers = traj[traj["vehicle_id"].isin(ids[7:])]
    assert followers["predecessor_in_view"].mean() > 0.8
