"""A circle of right of way: at a five-arm junction whose roads all have the same
priority, netconvert makes every link minor and the yields go round (the junction of
rand1_priority where a platoon stood for good at seed 43). Three cars standing at their
stop lines at once, A (a platoon car) yielding to B, B to C and C to A, wait for ever
in SUMO with teleports off. The platoon car takes the junction (loop.standoff)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
import sumolib

import platoon_sumo.cosim as cosim
from platoon_sumo.loop.standoff import STANDOFF_S, Standoffs
from platoon_sumo.runner import load_plan, run
from tests.helpers import build_net

#: The junction's arms, placed as in the random network (junction 44 of rand1_priority).
ARMS = {"a128": (-209.80, -118.23), "a52": (67.92, 113.40), "a58": (232.20, 44.74),
        "a70": (29.98, -117.43), "a34": (-73.87, 128.78)}  # fmt: skip
NODES = "<nodes>\n" + "\n".join(
    [' <node id="c" x="0" y="0" type="priority"/>']
    + [f' <node id="{a}" x="{x}" y="{y}" type="dead_end"/>' for a, (x, y) in ARMS.items()]
) + "\n</nodes>"  # fmt: skip
EDGES = "<edges>\n" + "\n".join(
    f' <edge id="{a}_{d}" from="{f}" to="{t}" numLanes="1" speed="13.89" priority="-1"/>'
    for a in ARMS for d, f, t in (("in", a, "c"), ("out", "c", a))
) + "\n</edges>"  # fmt: skip
#: B (from a52, left into a58) and C (from a128 into a52) stand at their stop lines
#: when the platoon car A (from a58, right into a34) departs at its own.
DEPART_S, STOP_LINE_GAP_M = 5.0, 1.0


@pytest.fixture(scope="module")
def circle(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, float]:
    """The network, B's and C's routes, and A's depart position."""
    d = tmp_path_factory.mktemp("circle")
    net = build_net(d, NODES, EDGES, None, "--no-turnarounds")
    near_end = {a: sumolib.net.readNet(str(net)).getEdge(f"{a}_in").getLength() - STOP_LINE_GAP_M
                for a in ARMS}  # fmt: skip
    routes = d / "circle.rou.xml"
    routes.write_text(
        "<routes>\n"
        ' <route id="b" edges="a52_in a58_out"/><route id="c" edges="a128_in a52_out"/>\n'
        f' <vehicle id="B" route="b" depart="{DEPART_S}" departSpeed="0"'
        f' departPos="{near_end["a52"]}"/>\n'
        f' <vehicle id="C" route="c" depart="{DEPART_S}" departSpeed="0"'
        f' departPos="{near_end["a128"]}"/>\n'
        "</routes>\n"
    )
    return net, routes, near_end["a58"]


def scenario(net: Path, routes: Path, depart_pos_m: float) -> dict:
    return {
        "simulation": {"step_s": 0.1, "end_s": 60.0, "seed": 1},
        "network": {"net_file": str(net)},
        "traffic": {"route_files": [str(routes)]},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": DEPART_S, "depart_pos_m": depart_pos_m,
            "route": {"edges": ["a58_in", "a34_out"]},
        }],
    }  # fmt: skip


def test_a_platoon_car_in_a_circle_of_right_of_way_takes_the_junction(
    circle, write_scenario, tmp_path
):
    out = run(load_plan(write_scenario(scenario(*circle))), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    events = pd.read_csv(out / "events.csv", keep_default_na=False)
    standoffs = events[events["kind"] == "standoff"]
    assert standoffs["vehicle_id"].tolist() == ["p.0"]
    assert standoffs["other_id"].tolist() == ["B"]
    # it stood the standoff time at its stop line (after creeping up to it), then went
    assert DEPART_S + STANDOFF_S <= standoffs["time_s"].iloc[0] <= DEPART_S + STANDOFF_S + 2.0
    assert summary["platoon_vehicles"]["arrived"] == 1
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0
    tripinfo = pd.read_csv(out / "tripinfo.csv", sep=";")
    assert set(tripinfo["tripinfo_id"]) == {"p.0", "B", "C"}  # the others went on too


def test_without_it_the_circle_holds_for_ever(
    circle, write_scenario, tmp_path, monkeypatch: pytest.MonkeyPatch
):
    stages = cosim.after_sumo_stages
    monkeypatch.setattr(
        cosim,
        "after_sumo_stages",
        lambda: [s for s in stages() if not isinstance(s, Standoffs)],
    )
    out = run(load_plan(write_scenario(scenario(*circle))), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    assert summary["platoon_vehicles"]["still_running"] == 1
