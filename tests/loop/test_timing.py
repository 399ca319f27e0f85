"""Where a run's CPU time goes (`--timings`): the laps' arithmetic on a scripted clock,
every part of the loop lapped once a step on the fake backend, and the file a real run
writes."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.cli import main
from platoon_sumo.cosim import CoSimulation, after_sumo_stages, before_sumo_stages
from platoon_sumo.loop.timing import (
    AFTER_SUMO,
    BEFORE_SUMO,
    HOOK,
    OUTSIDE,
    RECORD,
    SUMO,
    TIMING_COLUMNS,
    StageTimings,
    headline,
)
from tests.fakes import FakeBackend
from tests.loop.test_stages import Collector, plan


def scripted(times: list[float]):
    ticks = iter(times)
    return lambda: next(ticks)


def test_a_part_gets_the_time_since_the_last_lap_summed_over_steps() -> None:
    timings = StageTimings(scripted([0.0, 1.0, 3.0, 10.0, 10.5, 12.0]))
    for vehicles in (4, 6):
        timings.start()
        timings.lap("a", BEFORE_SUMO)
        timings.lap("SUMO step", SUMO)
        timings.end_step(vehicles)
    table = timings.table()
    assert list(table.columns) == list(TIMING_COLUMNS)
    assert table["part"].tolist() == ["SUMO step", "a"]  # dearest first
    sumo, a = table.iloc[0], table.iloc[1]
    assert (a.cpu_s, sumo.cpu_s) == (1.5, 3.5)  # the time between start and lap, not before
    assert sumo.share == 0.7 and math.isclose(table["share"].sum(), 1.0)
    assert sumo.us_per_step == 1.75e6 and a.us_per_platoon_vehicle_step == 1.5e5
    assert headline(table).endswith("; the loop's own 150000 µs per platoon vehicle-step")


def test_the_loops_own_cost_leaves_out_sumo_and_the_runs_start_and_end() -> None:
    timings = StageTimings(scripted([0.0, 2.0, 5.0, 6.0]))
    timings.start()
    timings.lap("SUMO step", SUMO)
    timings.lap("Decide", BEFORE_SUMO)
    timings.lap("recorder", HOOK)
    timings.end_step(2)
    timings.add("start and end", OUTSIDE, 10.0)
    text = headline(timings.table(), parts=2)
    assert text == (
        "CPU by part: start and end 62 %, Decide 19 %; "
        "the loop's own 2000000 µs per platoon vehicle-step"
    )  # (3 + 1) s over 2 vehicle-steps
    empty = StageTimings(scripted([0.0, 1.0]))
    empty.start()
    empty.lap("SUMO step", SUMO)
    empty.end_step(0)
    assert headline(empty.table()) == "CPU by part: SUMO step 100 %"  # no platoon vehicle


def test_every_stage_sumos_step_the_record_and_each_hook_are_lapped_once_a_step(
    write_scenario,
) -> None:
    clock = itertools.count()  # one tick a read: each part's time is its laps
    timings = StageTimings(lambda: float(next(clock)))
    sim = CoSimulation(plan(write_scenario), FakeBackend(), [Collector()], timings=timings)
    vehicles = sum(len(sim.step().columns) for _ in range(5))
    expected = (
        [(type(s).__name__, BEFORE_SUMO) for s in before_sumo_stages()]
        + [("SUMO step", SUMO)]
        + [(type(s).__name__, AFTER_SUMO) for s in after_sumo_stages()]
        + [("step record", RECORD), ("Collector", HOOK)]
    )
    assert list(timings.cpu_s) == expected  # in the order they ran
    assert set(timings.cpu_s.values()) == {5.0}
    assert (timings.steps, timings.vehicle_steps) == (5, vehicles) and vehicles > 0


def test_a_run_with_timings_writes_them_and_says_where_the_time_went(
    write_scenario, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = write_scenario(
        {
            "simulation": {"step_s": 0.1, "end_s": 8.0},
            "network": {"net_file": str(Path(__file__).parents[2] / "networks" / "straight"
                                         / "straight.net.xml")},
            "platoons": [{"id": "p", "route": {"edges": ["WE"]}, "members": 2,
                          "depart_pos_m": 100.0}],
        }
    )  # fmt: skip
    out = tmp_path / "run"
    assert main(["run", str(scenario), "--out", str(out), "--quiet", "--timings"]) == 0
    table = pd.read_csv(out / "timings.csv")
    assert list(table.columns) == list(TIMING_COLUMNS)
    parts = set(table["part"])
    stages = {type(s).__name__ for s in [*before_sumo_stages(), *after_sumo_stages()]}
    assert stages | {"SUMO step", "step record", "TrajectoryRecorder", "start and end"} <= parts
    assert (table["cpu_s"] >= 0).all() and math.isclose(table["share"].sum(), 1.0, abs_tol=1e-3)
    steps = json.loads((out / "summary.json").read_text())["steps"]
    assert (table["us_per_step"] * steps / 1e6 - table["cpu_s"]).abs().max() < 1e-3
    said = capsys.readouterr().out
    assert "CPU by part: " in said and "µs per platoon vehicle-step" in said
