"""A car beside its lane's centre line crosses a sharp bend of the lane's shape without
SUMO jumping it along the road (sublane actuation, `SumoBackend.bends_ahead`).

SUMO puts a car's front at its lateral offset square to the shape's segment under it:
where a lane's shape turns by 30 degrees at one vertex, a car 3.5 m left of the centre
of a 10 m lane moves 2 x 3.5 x sin(15 degrees) = 1.8 m forward at once (the race
circuit's invented on-ramp put a follower onto its leader so). A weaving leader asked to
drive 3.5 m beside its lane's centre is brought towards the centre before the bend, to
where the jump stays within `LANDING_SHIFT_M`, and back out after it."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from platoon_sumo.sumo import backend
from tests.helpers import REPO, build_net

PLUGINS = REPO / "tests" / "plugins"
TURN_RAD = math.radians(30.0)
BEND_X = 200.0
END = f"{BEND_X + 200.0 * math.cos(TURN_RAD):.3f},{-200.0 * math.sin(TURN_RAD):.3f}"
NODES = f"""<nodes><node id="W" x="0" y="0"/>
  <node id="E" x="{END.split(",")[0]}" y="{END.split(",")[1]}"/>
</nodes>"""
EDGES = f"""<edges><edge id="WE" from="W" to="E" numLanes="1" speed="13.9" width="10">
  <lane index="0" shape="0,0 {BEND_X},0 {END}"/>
</edge></edges>"""
OFFSET_M, SPEED_MPS = 3.5, 5.0


@pytest.fixture(autouse=True)
def plugins_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))


def drive_through(tmp_path, write_scenario) -> pd.DataFrame:
    net = build_net(tmp_path, NODES, EDGES, None, "--no-turnarounds")
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 80.0, "seed": 1, "lateral_resolution_m": 0.4},
        "network": {"net_file": str(net)},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 1.0, "actuation": "sublane",
            "depart_pos_m": 20.0, "route": {"edges": ["WE"]},
            "leader": {"type": "weave:Weave",
                       "params": {"speed_mps": SPEED_MPS, "offset_m": OFFSET_M, "from_s": 5.0}},
        }],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    assert json.loads((out / "summary.json").read_text())["collisions"] == 0
    return pd.read_csv(out / "trajectories.csv")


def largest_jump_m(traj: pd.DataFrame) -> float:
    """The largest step of the car beyond the distance its speed drove [m]."""
    step = np.hypot(traj["x_m"].diff(), traj["y_m"].diff())
    driven = 0.5 * (traj["speed_mps"] + traj["speed_mps"].shift()) * traj["time_s"].diff()
    return float((step - driven).abs().max())


def test_a_car_beside_the_centre_crosses_a_sharp_bend_without_a_jump(tmp_path, write_scenario):
    traj = drive_through(tmp_path, write_scenario)
    assert largest_jump_m(traj) < backend.LANDING_SHIFT_M
    offset = traj.set_index("time_s")["lateral_offset_m"]
    assert (offset.loc[20.0:30.0] - OFFSET_M).abs().max() < 0.3  # beside, before the bend
    assert (offset.iloc[-50:] - OFFSET_M).abs().max() < 0.3  # and again after it


def test_without_the_bound_sumo_jumps_the_car(tmp_path, write_scenario, monkeypatch):
    def unbounded(self, vehicle_ids):
        return np.full(len(vehicle_ids), np.inf), np.full(len(vehicle_ids), np.inf)

    monkeypatch.setattr(backend.SumoBackend, "bends_ahead", unbounded)
    traj = drive_through(tmp_path, write_scenario)
    assert largest_jump_m(traj) > 1.0
