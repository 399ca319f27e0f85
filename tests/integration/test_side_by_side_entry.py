"""Two cars side by side on one wide lane (sublane model) going on into one junction lane
too narrow for both: SUMO's right of way does not order them (one lane, one link), so
the platoon car waits at the line for a SUMO car beside it that drives in, where that
helps (`loop.obstacles.ObstaclesAhead._entering`).

A 6 m lane ends at a light, then a 3.2 m lane. The platoon car (a test controller
holding it right of the lane's centre) stops at red; a SUMO car keeping to the left of
its lanes comes up beside it as the light turns green. The race circuit (seed 44) had
such a pair enter a left turn together: the platoon car stood in the junction behind
the other, which waited at the exit to move over, for the rest of the run."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from platoon_sumo.loop import obstacles
from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO, build_net

PLUGINS = REPO / "tests" / "plugins"
GREEN_S = 40.0


@pytest.fixture(autouse=True)
def plugins_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))


def scenario(tmp_path, turn: bool, depart_s: float) -> dict:
    """A junction of radius 8 m with a road north (the left turn: a 16.6 m junction lane)
    and one east; or netconvert's junction with the road east only (straight on: a 3 m
    junction lane). The SUMO car `h` departs at `depart_s`."""
    radius, exit_to = (' radius="8"', "N") if turn else ("", "E")
    # straight on, lanes centred on the edges' lines: both lanes' centres in line (with
    # the default spread the junction lane moves the car 1.4 m left as it crosses)
    spread = "" if turn else ' spreadType="center"'
    nodes = f"""<nodes><node id="W" x="0" y="0"/>
      <node id="J" x="200" y="0" type="traffic_light"{radius}/>
      <node id="N" x="200" y="100"/><node id="E" x="300" y="0"/></nodes>"""
    edges = "".join(
        f'<edge id="{e}" from="{a}" to="{b}" numLanes="1" speed="13.9" width="{w}"{spread}/>'
        for e, a, b, w in [("WJ", "W", "J", 6), ("JN", "J", "N", 3.2), ("JE", "J", "E", 3.2)]
        if turn or e != "JN"
    )
    net = build_net(tmp_path, nodes, f"<edges>{edges}</edges>", None, "--no-turnarounds")
    red, green = ("rr", "GG") if turn else ("r", "G")
    (tmp_path / "light.add.xml").write_text(
        f"""<additional><tlLogic id="J" type="static" programID="test" offset="0">
        <phase duration="{GREEN_S}" state="{red}"/><phase duration="1000" state="{green}"/>
        </tlLogic></additional>""",
        encoding="utf-8",
    )
    (tmp_path / "left.rou.xml").write_text(
        f"""<routes><vType id="keeps_left" latAlignment="left"/>
        <vehicle id="h" type="keeps_left" depart="{depart_s}" departPos="20"
         departPosLat="left" departSpeed="max"><route edges="WJ J{exit_to}"/></vehicle>
        </routes>""",
        encoding="utf-8",
    )
    return {
        "simulation": {"step_s": 0.1, "end_s": 90.0, "seed": 1, "lateral_resolution_m": 0.4},
        "network": {"net_file": str(net), "additional_files": [str(tmp_path / "light.add.xml")]},
        "traffic": {"route_files": [str(tmp_path / "left.rou.xml")]},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 1.0, "actuation": "sublane",
            "depart_pos_m": 20.0, "route": {"edges": ["WJ", f"J{exit_to}"]},
            "leader": {"type": "weave:Weave",
                       "params": {"speed_mps": 8.0, "offset_m": -1.2, "from_s": 0.0}},
        }],
    }  # fmt: skip


def drive(tmp_path, write_scenario, turn: bool, depart_s: float):
    sc = scenario(tmp_path, turn, depart_s)
    out = run(load_plan(write_scenario(sc)), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    return summary, pd.read_csv(out / "trajectories.csv")


def test_the_platoon_car_lets_the_car_beside_it_into_a_left_turn_first(tmp_path, write_scenario):
    summary, traj = drive(tmp_path, write_scenario, turn=True, depart_s=27.0)
    assert summary["collisions"] == 0
    assert summary["all_vehicles"] == {"departed": 2, "arrived": 2}
    waited = traj[(traj["time_s"] > GREEN_S + 1.0) & traj["lane_id"].str.startswith("WJ")]
    assert len(waited) > 20  # it stood at the line after green while the car went in
    assert (waited["supervisor"] == "emergency").any()
    assert traj[traj["lane_id"].str.startswith(":")]["speed_mps"].min() > 1.0  # not in it


def test_without_waiting_the_two_touch_in_the_turn(tmp_path, write_scenario, monkeypatch):
    def nobody(self, ctx, members, table, stop_m):
        empty = np.empty(0, dtype=np.int64)
        return empty, empty, empty, np.empty(0)

    monkeypatch.setattr(obstacles.ObstaclesAhead, "_entering", nobody)
    summary, _ = drive(tmp_path, write_scenario, turn=True, depart_s=27.0)
    assert summary["collisions_platoon_at_fault"] >= 1


@pytest.mark.parametrize("depart_s", [25.0, 26.0, 27.0])
def test_through_a_short_junction_lane_the_platoon_car_goes_first(
    tmp_path, write_scenario, depart_s
):
    """Its 3 m junction lane leaves the SUMO car's back beside the line when it stands
    at the exit to move over: a platoon car waiting there would block that move for
    good, so it does not wait (whether the other car stands beside it or drives up)."""
    summary, traj = drive(tmp_path, write_scenario, turn=False, depart_s=depart_s)
    assert summary["collisions"] == 0
    assert summary["all_vehicles"] == {"departed": 2, "arrived": 2}
    assert summary["gridlocks"] == 0
    assert traj[traj["lane_id"].str.startswith(":")]["speed_mps"].min() > 1.0
