"""A car beside its lane's centre line crosses sharp bends of the lane's shape without
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
OFFSET_M = 3.5


def shape(turns_deg: list[float], pieces_m: list[float]) -> list[tuple[float, float]]:
    """A lane's shape: 200 m east, then pieces of the given lengths, each turned by the
    given angle from the one before (right: negative)."""
    points, heading = [(0.0, 0.0), (200.0, 0.0)], 0.0
    for turn, length in zip(turns_deg, pieces_m, strict=True):
        heading += math.radians(turn)
        x, y = points[-1]
        points.append((x + length * math.cos(heading), y + length * math.sin(heading)))
    return points


#: One vertex turning by 30 degrees; and one of 8 degrees 3 m before one of 30, which
#: hides the sharp one from a car that looks at the next vertex only.
SHAPES = {
    "one_sharp_vertex": shape([-30.0], [200.0]),
    "mild_before_sharp": shape([-8.0, -30.0], [3.0, 200.0]),
}


def network(tmp_path, points: list[tuple[float, float]]):
    text = " ".join(f"{x:.3f},{y:.3f}" for x, y in points)
    (x0, y0), (x1, y1) = points[0], points[-1]
    nodes = f"""<nodes><node id="W" x="{x0}" y="{y0}"/>
      <node id="E" x="{x1:.3f}" y="{y1:.3f}"/></nodes>"""
    edges = f"""<edges><edge id="WE" from="W" to="E" numLanes="1" speed="13.9" width="10">
      <lane index="0" shape="{text}"/></edge></edges>"""
    return build_net(tmp_path, nodes, edges, None, "--no-turnarounds")


@pytest.fixture(autouse=True)
def plugins_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))


def drive_through(tmp_path, write_scenario, layout: str, speed_mps: float) -> pd.DataFrame:
    net = network(tmp_path, SHAPES[layout])
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 80.0, "seed": 1, "lateral_resolution_m": 0.4},
        "network": {"net_file": str(net)},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 1.0, "actuation": "sublane",
            "depart_pos_m": 20.0, "route": {"edges": ["WE"]},
            "leader": {"type": "weave:Weave",
                       "params": {"speed_mps": speed_mps, "offset_m": OFFSET_M, "from_s": 5.0}},
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


@pytest.mark.parametrize(
    ("layout", "speed_mps"),
    [("one_sharp_vertex", 5.0), ("mild_before_sharp", 5.0), ("mild_before_sharp", 12.0)],
)
def test_a_car_beside_the_centre_crosses_a_sharp_bend_without_a_jump(
    tmp_path, write_scenario, layout, speed_mps
):
    traj = drive_through(tmp_path, write_scenario, layout, speed_mps)
    assert largest_jump_m(traj) < backend.LANDING_SHIFT_M
    offset = traj.set_index("time_s")["lateral_offset_m"]
    before = traj[traj["route_s_m"] < 190.0]
    assert (before["lateral_offset_m"] - OFFSET_M).abs().min() < 0.2  # beside, before
    assert (offset.iloc[-30:] - OFFSET_M).abs().max() < 0.3  # and again after it


def test_without_the_bound_sumo_jumps_the_car(tmp_path, write_scenario, monkeypatch):
    def unbounded(self, vehicle_ids):
        return np.full((len(vehicle_ids), 1), np.inf), np.full((len(vehicle_ids), 1), np.inf)

    monkeypatch.setattr(backend.SumoBackend, "bends_ahead", unbounded)
    traj = drive_through(tmp_path, write_scenario, "one_sharp_vertex", 5.0)
    assert largest_jump_m(traj) > 1.0
