"""Sublane actuation does not move a car sideways into a car beside it: a weaving leader
(`tests/plugins/weave.py`) asked to move a lane over waits while a SUMO car drives
alongside in that lane and moves once it has gone; without the check it drives into
the car's side (platoon_sumo.kernels.sideways)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from platoon_sumo import actuation
from platoon_sumo.loop.context import VehicleRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO, KeptByTheLeader

STRAIGHT_NET = REPO / "networks" / "straight" / "straight.net.xml"
PLUGINS = REPO / "tests" / "plugins"
NEIGHBOUR = "neighbour"
#: The neighbour drives beside the leader until this time [s]; the leader is asked to
#: move to the next lane (3.5 m to its left) from 15 s.
ALONGSIDE_UNTIL_S = 35.0


@pytest.fixture(autouse=True)
def plugins_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))


class Alongside(KeptByTheLeader):
    """A SUMO car kept beside the leader's front bumper on the left lane (y -1.75)."""

    def __init__(self) -> None:
        super().__init__(NEIGHBOUR, "WE", 1, "p.0", ALONGSIDE_UNTIL_S)

    def where(self, leader: VehicleRecord) -> tuple[float, float]:
        return leader.front_x_m, -1.75


def run_weave(write_scenario, tmp_path) -> tuple[dict, pd.DataFrame, Alongside]:
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 60.0, "seed": 1, "lateral_resolution_m": 0.4},
        "network": {"net_file": str(STRAIGHT_NET)},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 1.0, "depart_lane": 0, "actuation": "sublane",
            "route": {"edges": ["WE"]},
            "leader": {"type": "weave:Weave", "params": {"offset_m": 3.5, "from_s": 15.0}},
        }],
    }  # fmt: skip
    hook = Alongside()
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out", [hook]).directory
    summary = json.loads((out / "summary.json").read_text())
    return summary, pd.read_csv(out / "trajectories.csv"), hook


def test_a_car_waits_to_move_over_while_another_drives_beside_it(write_scenario, tmp_path):
    summary, traj, hook = run_weave(write_scenario, tmp_path)
    assert hook.state == "gone"
    assert summary["collisions"] == 0
    offset = traj.set_index("time_s")["lateral_offset_m"]
    assert offset.loc[15.0:ALONGSIDE_UNTIL_S].abs().max() < 0.5  # held off the neighbour
    assert offset.loc[ALONGSIDE_UNTIL_S + 15.0 :].min() > 3.0  # over once it has gone


def test_without_the_check_it_drives_into_the_car_beside(
    write_scenario, tmp_path, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setattr(actuation, "sideways_conflicts", lambda *a: np.zeros(len(a[3]), bool))
    summary, _, _ = run_weave(write_scenario, tmp_path)
    assert summary["collisions"] > 0
