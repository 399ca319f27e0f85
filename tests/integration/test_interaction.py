"""SUMO's drivers react to platoon vehicles; runs are reproducible."""

from __future__ import annotations

import numpy as np
import pytest

from platoon_sumo.loop.context import RunContext, RunOutcome, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET

EAST = ["left1A1", "A1B1", "B1C1", "C1right1"]


def straight_scenario(end_s: float = 70.0) -> dict:
    """Our car stops at the red light of A1 (east-west is red for the first 45 s);
    SUMO cars of one flow follow it on the same lane."""
    return {
        "simulation": {"step_s": 0.1, "end_s": end_s, "seed": 7},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "traffic": {
            "vehicle_types": [
                {"id": "human", "car_follow_model": "Krauss", "sigma": 0.0, "min_gap_m": 2.5}
            ],
            "flows": [
                {
                    "from_edge": "left1A1",
                    "to_edge": "C1right1",
                    "vehs_per_hour": 900,
                    "begin_s": 3.0,
                    "end_s": 30.0,
                    "type": "human",
                }
            ],
        },
        "platoons": [
            {
                "id": "ego",
                "route": {"edges": EAST},
                "depart_s": 0.0,
                "depart_lane": 0,
                "leader": {"type": "route_following", "params": {"cruise_speed_mps": 8.0}},
            }
        ],
    }


class GapBehindEgo:
    """Bumper-to-bumper gap of the SUMO car directly behind the ego on its lane."""

    def __init__(self) -> None:
        self.gaps: list[tuple[float, str, float, float, float]] = []

    def on_start(self, run: RunContext) -> None:
        pass

    def on_end(self, outcome: RunOutcome) -> None:
        pass

    def on_step(self, record: StepRecord) -> None:
        w = record.world
        if "ego.0" not in w.index:
            return
        e = w.index["ego.0"]
        ego_rear_x = w.front_x_m[e] - w.length_m[e]  # heading east on a straight road
        behind = [
            (ego_rear_x - w.front_x_m[i], vid)
            for vid, i in w.index.items()
            if vid != "ego.0" and w.lane_ids[i] == w.lane_ids[e] and w.front_x_m[i] < ego_rear_x
        ]
        if behind:
            gap, vid = min(behind)
            i = w.index[vid]
            self.gaps.append((record.time_s, vid, gap, w.speed_mps[e], w.speed_mps[i]))


def test_sumo_car_brakes_for_stopped_platoon_vehicle(write_scenario, tmp_path):
    watcher = GapBehindEgo()
    result = run(load_plan(write_scenario(straight_scenario())), tmp_path / "out", [watcher])
    assert result.summary["collisions"] == 0
    gaps = np.array([g[2] for g in watcher.gaps])
    ego_speed = np.array([g[3] for g in watcher.gaps])
    follower_speed = np.array([g[4] for g in watcher.gaps])
    # The situation happened: the ego stood still with a SUMO car stopped close behind it.
    stopped_close = (ego_speed < 0.01) & (follower_speed < 0.01) & (gaps < 5.0)
    assert stopped_close.sum() > 50
    # SUMO's driver kept at least its minGap (2.5 m) at every step.
    assert gaps.min() >= 2.5 - 1e-6


@pytest.mark.slow
def test_same_scenario_and_seed_give_identical_outputs(write_scenario, tmp_path):
    scenario = write_scenario(
        {
            "simulation": {"step_s": 0.1, "end_s": 90.0, "seed": 3},
            "network": {"net_file": str(URBAN_GRID_NET)},
            "traffic": {
                "vehicle_types": [{"id": "h", "car_follow_model": "Krauss", "sigma": 0.5}],
                "random_trips": {"period_s": 1.0},
            },
            "platoons": [
                {
                    "id": "p",
                    "route": {"from_edge": "left0A0", "to_edge": "C2right2"},
                    "members": 2,
                    "depart_s": 5.0,
                }
            ],
        }
    )
    first = run(load_plan(scenario), tmp_path / "a").directory
    second = run(load_plan(scenario), tmp_path / "b").directory
    # The copy in a results folder repeats the run on its own (absolute paths, seed, times).
    third = run(load_plan(first / "scenario.yaml"), tmp_path / "c").directory
    for name in ("trajectories.csv", "tripinfo.csv"):
        assert (first / name).read_bytes() == (second / name).read_bytes(), name
        assert (first / name).read_bytes() == (third / name).read_bytes(), name
    assert (first / "trajectories.csv").stat().st_size > 10_000


def test_a_relative_results_folder_works_from_any_working_directory(
    write_scenario, tmp_path, monkeypatch
):
    scenario = write_scenario(
        {
            "simulation": {"step_s": 0.1, "end_s": 20.0, "seed": 1},
            "network": {"net_file": str(URBAN_GRID_NET)},
            "traffic": {"random_trips": {"period_s": 2.0}},
            "platoons": [{"id": "p", "route": {"edges": EAST}, "depart_s": 1.0}],
        }
    )
    workdir = tmp_path / "work"
    workdir.mkdir()
    monkeypatch.chdir(workdir)
    result = run(load_plan(scenario), "results/relative")
    assert result.summary["status"] == "complete"
    assert (workdir / "results" / "relative" / "inputs" / "random.trips.xml").is_file()
