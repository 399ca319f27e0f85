"""Acceptance of the foundation on the real SUMO: scenarios/urban_grid.yaml."""

from __future__ import annotations

import json
from pathlib import Path

import libsumo
import pandas as pd
import pytest

from platoon_sumo.loop.context import RunContext, RunOutcome, StepRecord
from platoon_sumo.runner import load_plan, run
from platoon_sumo.sumo.network import Network
from tests.helpers import REPO, URBAN_GRID_NET

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out


class TrafficAroundEgo:
    """Counts the SUMO vehicles in the network while the platoon vehicle drives, and
    checks the loop's running count against SUMO's own list every step."""

    def __init__(self) -> None:
        self.max_sumo_vehicles_while_active = 0
        self.count_mismatches: list[tuple[float, int, int]] = []

    def on_start(self, run: RunContext) -> None:
        pass

    def on_step(self, record: StepRecord) -> None:
        listed = libsumo.vehicle.getIDCount()
        if record.sumo_vehicles != listed:
            self.count_mismatches.append((record.time_s, record.sumo_vehicles, listed))
        if record.vehicles:
            sumo_vehicles = record.sumo_vehicles - len(record.vehicles)
            self.max_sumo_vehicles_while_active = max(
                self.max_sumo_vehicles_while_active, sumo_vehicles
            )

    def on_end(self, outcome: RunOutcome) -> None:
        pass


@pytest.fixture(scope="module")
def urban_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, TrafficAroundEgo]:
    out = tmp_path_factory.mktemp("urban_grid")
    counter = TrafficAroundEgo()
    run(load_plan(REPO / "scenarios" / "urban_grid.yaml"), out_dir=out, hooks=[counter])
    return out, counter


def signalised_junctions_crossed(lanes: pd.Series) -> list[str]:
    """Junction ids of the internal lanes driven, in order, that carry a traffic light."""
    tls = set(Network(URBAN_GRID_NET).tls_ids())
    crossed: list[str] = []
    for lane in lanes:
        if lane.startswith(":"):
            junction = lane[1:].rsplit("_", 2)[0]
            if junction in tls and (not crossed or crossed[-1] != junction):
                crossed.append(junction)
    return crossed


def test_car_crosses_signalised_junctions_safely_among_traffic(urban_run):
    out, counter = urban_run
    summary = json.loads((out / "summary.json").read_text())
    traj = pd.read_csv(out / "trajectories.csv")

    assert summary["status"] == "complete"
    assert summary["platoon_vehicles"]["arrived"] == summary["platoon_vehicles"]["planned"] == 1
    assert summary["collisions"] == 0
    assert summary["teleports"] == 0
    assert summary["red_light_violations"] == 0
    assert counter.max_sumo_vehicles_while_active >= 100
    assert counter.count_mismatches == []
    assert len(signalised_junctions_crossed(traj["lane_id"])) >= 3


def test_car_stays_within_its_lanes(urban_run):
    out, _ = urban_run
    traj = pd.read_csv(out / "trajectories.csv")
    assert (traj["lateral_offset_m"].abs() < traj["lane_width_m"] / 2).all()
    # and it really drove the turns (not only straight lanes)
    assert traj["yaw_rad"].max() - traj["yaw_rad"].min() > 2.5


def test_car_stops_at_red_at_the_line_or_behind_the_queue(urban_run):
    out, _ = urban_run
    traj = pd.read_csv(out / "trajectories.csv")
    stopped_at_red = traj[(traj["speed_mps"] < 0.01) & (traj["signal_state"] == "r")]
    assert len(stopped_at_red) > 10, "the scenario is meant to meet a red light"
    at_line = stopped_at_red["signal_distance_m"].between(0.0, 3.0)
    in_queue = stopped_at_red["ahead_gap_m"].between(1.0, 4.0) & (
        stopped_at_red["ahead_gap_m"] < stopped_at_red["signal_distance_m"]
    )
    assert (at_line | in_queue).all()


def test_tripinfo_lists_every_vehicle(urban_run):
    out, _ = urban_run
    trips = pd.read_csv(out / "tripinfo.csv", sep=";")
    summary = json.loads((out / "summary.json").read_text())
    assert "ego.0" in set(trips["tripinfo_id"])
    assert len(trips) >= summary["all_vehicles"]["arrived"]
    assert summary["versions"]["sumo"].startswith("SUMO 1.")
    assert len(summary["scenario_sha256"]) == 64
