"""A laser follower whose predecessor vanishes while it turns inside a junction drives
out of the junction before it stops (``leave_junctions``); a platoon vehicle taken out
of SUMO by a hook leaves the run as removed."""

from __future__ import annotations

import json

import libsumo
import pandas as pd
import pytest

from platoon_sumo.loop.context import StepHook, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET


class RemoveLeaderInJunction(StepHook):
    """Takes the leader out of SUMO (libsumo, as any hook may) once its follower is on
    a junction's internal lane."""

    def __init__(self) -> None:
        self.at_s: float | None = None

    def on_step(self, record: StepRecord) -> None:
        world = record.world
        if self.at_s is not None or "p.0" not in world.index or "p.1" not in world.index:
            return
        if world.lane_ids[world.index["p.1"]].startswith(":"):
            libsumo.vehicle.remove("p.0")
            self.at_s = record.time_s


@pytest.mark.parametrize("leave_junctions", [True, False])
def test_follower_lost_inside_a_junction_drives_out_before_stopping(
    write_scenario, tmp_path, leave_junctions
):
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 60.0, "seed": 3},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{
            "id": "p", "members": 2, "spacing_m": 8.0, "depart_s": 1.0,
            # no powertrain lag: without leave_junctions the follower stops 1 m short
            # of the junction's end, which a car's lag carries it past
            "vehicle": {"actuator_lag_s": 0.0},
            "route": {"edges": ["left1A1", "A1B1", "B1B2", "B2top1"]},
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                         "params": {"on_lost": "stop", "leave_junctions": leave_junctions}},
        }],
    }  # fmt: skip
    hook = RemoveLeaderInJunction()
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out", [hook]).directory
    assert hook.at_s is not None, "the follower never entered the junction behind its leader"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["removed_off_route"] == [
        {"time_s": hook.at_s, "vehicle_id": "p.0", "reason": "taken out of SUMO outside the loop"}
    ]
    traj = pd.read_csv(out / "trajectories.csv")
    after = traj[(traj["vehicle_id"] == "p.1") & (traj["time_s"] > hook.at_s)]
    in_junction = after["lane_id"].str.startswith(":")
    assert after["speed_mps"].iloc[-1] == 0.0  # lost, it stopped (on_lost: stop)
    if leave_junctions:
        assert (after.loc[in_junction, "speed_mps"] > 1.0).all()
        assert after["lane_id"].iloc[-1] == "A1B1_0"  # out of the junction, on its route
    else:  # the behaviour it replaces: standing inside the junction
        assert after["lane_id"].iloc[-1].startswith(":")
    assert summary["collisions"] == 0
