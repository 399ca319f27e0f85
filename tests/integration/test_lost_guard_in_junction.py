"""A lost laser follower drives out of a junction past a car standing close beside its
path. On the unrepaired DRT district a follower that had lost its predecessor entered a
joined junction where an oncoming car waited 0.1-0.2 m beside its path (outside the
loop's corridor, inside the guard's band of a quarter width beside the body): the laser
guard of its route-following fallback stopped it there, and the waiting car stood there
too until the end (3 of 24 cars never arrived). With the
body in a junction the band keeps `guard_margin_junction_m` (5 cm) beside the body."""

from __future__ import annotations

import json

import libsumo
import pandas as pd

from platoon_sumo.loop.context import StepHook, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET, add_standing_car

BLOCKER = "blocker"
#: Junction B1 spans x 289.6 to 310.4; the car drives the eastbound inner lane's centre,
#: y 298.4, its left side at 299.3. The blocker, 3 m wide and facing west, stands with
#: its front at x 302 and its side at y 299.55: 0.25 m beside the car's body, outside
#: the loop's corridor (0.2 m) and inside the guard's band (0.45 m).
FRONT_X, CENTRE_Y, WIDTH_M = 302.0, 301.05, 3.0
#: The blocker appears once the car's front is this far east, inside the junction [m].
PLACE_AT_X = 292.0


class Blocker(StepHook):
    """A car standing at (FRONT_X, CENTRE_Y) from when `p.0` has entered the junction."""

    def __init__(self) -> None:
        self.placed = False

    def on_step(self, record: StepRecord) -> None:
        if not self.placed:
            if "p.0" not in libsumo.vehicle.getIDList():
                return
            x, _ = libsumo.vehicle.getPosition("p.0")
            if x < PLACE_AT_X:
                return
            add_standing_car(BLOCKER, ["C1B1", "B1A1"], WIDTH_M, "1", "150")
            self.placed = True
        libsumo.vehicle.setSpeed(BLOCKER, 0.0)
        libsumo.vehicle.moveToXY(BLOCKER, "", -1, FRONT_X, CENTRE_Y, 270.0, keepRoute=2)


def run_lost_car(write_scenario, tmp_path, junction_margin_m: float | None):
    params: dict = {"on_lost": "route_following"}
    if junction_margin_m is not None:
        params["guard_margin_junction_m"] = junction_margin_m
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 90.0, "seed": 1, "lateral_resolution_m": 0.8},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 5.0, "depart_lane": 1,
            "actuation": "sublane", "route": {"edges": ["A1B1", "B1C1", "C1right1"]},
            "leader": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                       "params": {**params, "fallback": {"cruise_speed_mps": 8.0}}},
        }],
    }  # fmt: skip
    blocker = Blocker()
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out", [blocker]).directory
    summary = json.loads((out / "summary.json").read_text())
    return summary, pd.read_csv(out / "trajectories.csv"), blocker


def test_a_lost_car_drives_out_of_a_junction_past_a_car_close_beside_its_path(
    write_scenario, tmp_path
):
    summary, traj, blocker = run_lost_car(write_scenario, tmp_path, None)
    assert blocker.placed
    before = traj[traj["x_m"] < FRONT_X]
    assert set(before["controller_mode"].dropna()) == {"route_following"}  # lost
    assert summary["collisions"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 1
    passing = traj[(traj["x_m"] > FRONT_X - 2.0) & (traj["x_m"] < FRONT_X + 5.0)]
    assert len(passing) > 0 and passing["speed_mps"].min() > 1.0  # it did not stop there


def test_with_the_wide_margin_in_junctions_it_stops_there_for_good(write_scenario, tmp_path):
    # a quarter of the 1.8 m width, as outside junctions
    summary, traj, blocker = run_lost_car(write_scenario, tmp_path, 0.45)
    assert blocker.placed
    assert summary["collisions"] == 0
    assert summary["platoon_vehicles"]["arrived"] == 0
    last = traj.iloc[-1]
    assert last["lane_id"].startswith(":") and last["speed_mps"] < 0.1
    assert last["x_m"] < FRONT_X
