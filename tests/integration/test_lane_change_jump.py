"""A lane change that SUMO would put down onto another car waits (sublane actuation).

SUMO's sublane model keeps a car's lane position when it changes lanes. On an edge
whose lanes are not side by side at one lane position (here the left lane bulges 40 m
out and back, so that it is 9 % longer than the right one, as lanes of different
lengths are on a tight curve or a ramp netconvert guessed), a car crossing over beyond
the bulge lands about 7 m behind where it drove. A weaving leader asked to move a lane
over at 2 m/s while a car stands at that landing spot waits until the car has gone;
without the check (`actuation.landing_conflicts`) SUMO puts it down onto the car."""

from __future__ import annotations

import json
import math

import libsumo
import numpy as np
import pandas as pd
import pytest

from platoon_sumo import actuation
from platoon_sumo.loop.context import VehicleRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO, KeptByTheLeader, build_net

PLUGINS = REPO / "tests" / "plugins"
NODES = '<nodes><node id="W" x="0" y="0"/><node id="E" x="400" y="0"/></nodes>'
EDGES = """<edges><edge id="WE" from="W" to="E" numLanes="2" speed="13.9">
  <lane index="0" shape="0,-1.6 400,-1.6"/>
  <lane index="1" shape="0,1.6 100,1.6 150,41.6 200,1.6 400,1.6"/>
</edge></edges>"""
BLOCKER = "blocker"
#: The blocker stands where the leader would land until this time [s]; the leader is
#: asked to move a lane over from `FROM_S`, past the bulge.
BLOCKED_UNTIL_S, FROM_S = 40.0, 20.0


@pytest.fixture(autouse=True)
def plugins_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))


class AtTheLanding(KeptByTheLeader):
    """A car kept on the left lane at the leader's lane position: where SUMO puts the
    leader down when it changes lanes."""

    def __init__(self) -> None:
        super().__init__(BLOCKER, "WE", 1, "p.0", BLOCKED_UNTIL_S)
        self.behind_m: list[float] = []
        """How far behind the leader's front bumper the blocker has stood [m]."""

    def where(self, leader: VehicleRecord) -> tuple[float, float]:
        x, y = libsumo.simulation.convert2D("WE", libsumo.vehicle.getLanePosition("p.0"), 1)
        self.behind_m.append(leader.front_x_m - x)
        return x, y


def run_jump(tmp_path, write_scenario) -> tuple[dict, pd.DataFrame, AtTheLanding]:
    net = build_net(tmp_path, NODES, EDGES, None, "--no-turnarounds")
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 70.0, "seed": 1, "lateral_resolution_m": 0.4},
        "network": {"net_file": str(net)},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 1.0, "depart_lane": 0, "actuation": "sublane",
            "depart_pos_m": 230.0, "route": {"edges": ["WE"]},
            "leader": {"type": "weave:Weave",
                       "params": {"speed_mps": 2.0, "offset_m": 3.2, "from_s": FROM_S}},
        }],
    }  # fmt: skip
    hook = AtTheLanding()
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out", [hook]).directory
    summary = json.loads((out / "summary.json").read_text())
    return summary, pd.read_csv(out / "trajectories.csv"), hook


def test_a_lane_change_waits_while_sumo_would_put_it_down_onto_a_car(tmp_path, write_scenario):
    summary, traj, hook = run_jump(tmp_path, write_scenario)
    assert hook.state == "gone"
    assert min(hook.behind_m[int(FROM_S * 10) :]) > 5.0  # the jump is real: metres back
    assert summary["collisions"] == 0
    lane = traj.set_index("time_s")["lane_id"]
    assert (lane.loc[FROM_S:BLOCKED_UNTIL_S] == "WE_0").all()  # held on its lane
    assert (lane.loc[BLOCKED_UNTIL_S + 10.0 :] == "WE_1").all()  # over once it has gone


def test_without_the_check_sumo_puts_it_down_onto_the_car(
    tmp_path, write_scenario, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setattr(actuation, "landing_conflicts", lambda *a: np.zeros(len(a[3]), bool))
    summary, traj, _ = run_jump(tmp_path, write_scenario)
    assert summary["collisions"] > 0
    crossed = traj[traj["lane_id"] == "WE_1"]["time_s"].min()
    assert not math.isnan(crossed) and crossed < BLOCKED_UNTIL_S
