"""The first command a newcomer types: `platoon-sumo run` with the default scenario shows
a laser-only platoon among traffic and says what happened and what to type next."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from platoon_sumo.cli import DEFAULT_SCENARIO, main
from platoon_sumo.control.laser_follower import LaserFollower
from platoon_sumo.digest import run_digest
from platoon_sumo.runner import load_plan
from tests.helpers import REPO
from tests.integration.test_urban_grid import signalised_junctions_crossed


@pytest.fixture(scope="module")
def default_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("first") / "results"
    capture = pytest.MonkeyPatch()
    capture.chdir(REPO)  # as the README says: from the checkout, no scenario argument
    stdout = io.StringIO()
    try:
        with contextlib.redirect_stdout(stdout):
            code = main(["run", "--out", str(out), "--quiet"])
    finally:
        capture.undo()
    assert code == 0
    return out, stdout.getvalue()


@pytest.mark.slow
def test_default_scenario_is_a_laser_only_platoon_through_signals_and_turns(
    default_run: tuple[Path, str],
) -> None:
    plan = load_plan(REPO / DEFAULT_SCENARIO)
    followers = [m for p in plan.platoons for m in p.members if m.role == "follower"]
    assert len(followers) >= 2
    assert all(m.laser is not None and m.controller_cls is LaserFollower for m in followers)
    assert plan.scenario.traffic.random_trips is not None  # among SUMO's drivers
    traj = pd.read_csv(default_run[0] / "trajectories.csv")
    for vid, rows in traj.groupby("vehicle_id"):
        assert len(signalised_junctions_crossed(rows["lane_id"])) >= 2, vid
        assert rows["yaw_rad"].max() - rows["yaw_rad"].min() > 1.2, vid  # a turn at least


@pytest.mark.slow
def test_first_run_prints_the_numbers_of_its_summary(default_run: tuple[Path, str]) -> None:
    out, printed = default_run
    summary = json.loads((out / "summary.json").read_text())
    pv = summary["platoon_vehicles"]
    assert pv["arrived"] == pv["planned"] == 5
    assert f"{pv['arrived']}/{pv['planned']} arrived" in printed
    assert f"{summary['collisions']} collisions (" in printed
    humans = summary["sumo_collisions"] - summary["sumo_collisions_with_platoons"]
    assert f"{humans} collisions among human drivers" in printed
    assert "predecessor in view" in printed and "RMS spacing error" in printed


@pytest.mark.slow
def test_first_run_says_what_to_type_next(default_run: tuple[Path, str]) -> None:
    out, printed = default_run
    for command in ("report", "animate"):
        assert f"platoon-sumo {command} {out}" in printed
    assert f"platoon-sumo run {DEFAULT_SCENARIO} --gui" in printed


def _summary(**changes: Any) -> dict[str, Any]:
    summary: dict[str, Any] = {
        "scenario": "s", "simulated_s": 100.0, "wall_clock_s": 2.0, "real_time_factor": 50.0,
        "platoon_vehicles": {"planned": 3, "departed": 3, "arrived": 2, "still_running": 1},
        "collisions": 0, "collisions_platoon_at_fault": 0, "red_light_violations": 0,
        "emergency_brakings": 0, "sumo_collisions": 0, "sumo_collisions_with_platoons": 0,
        "teleports": 0, "gridlocks": 0, "followers": {},
    }  # fmt: skip
    summary.update(changes)
    return summary


def test_a_collision_between_human_drivers_is_reported_as_such() -> None:
    """The old last line said "0 collisions" while SUMO counted one between two humans."""
    text = run_digest(
        _summary(sumo_collisions=3, sumo_collisions_with_platoons=1, collisions=1),
        Path("/r"),
        Path("s.yaml"),
    )
    assert "1 collisions (0 caused by a platoon vehicle)" in text
    assert "2 collisions among human drivers" in text
    assert "1 still driving at the end" in text


def test_followers_line_names_the_worst_follower() -> None:
    followers = {
        "p": {
            "p.1": {"in_view_share": 1.0, "rms_spacing_error_m": 0.5, "min_gap_m": 3.0},
            "p.2": {"in_view_share": 0.5, "rms_spacing_error_m": 2.5, "min_gap_m": 1.0},
        }
    }
    text = run_digest(_summary(followers=followers), Path("/r"), Path("s.yaml"))
    assert "predecessor in view 75.0 % of steps (lowest 50.0 %, p.2)" in text
    assert "RMS spacing error 1.50 m (largest 2.50 m, p.2)" in text
    assert "closest gap 1.00 m (p.2)" in text
