"""The columnar ``RunStats`` against the row-by-row one it replaced
(``reference_stats.py``, the test oracle): the same vehicle, follower and platoon
summaries from the same steps, on random tables (missing cells, vehicles coming and
going, predecessors absent, a metrics window, supervisor states and vehicle limits) and on
the tables of real runs."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.events import Event, EventKind
from platoon_sumo.metrics.stats import RunStats, table_steps
from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO
from tests.metrics import reference_stats

NUMERIC = ("speed_mps", "accel_mps2", "jerk_mps3", "gap_to_predecessor_m", "measured_gap_m",
           "desired_gap_m", "spacing_error_m", "time_gap_s", "ttc_s",
           "lateral_deviation_m")  # fmt: skip


def feed_both(
    steps: list[tuple[float, pd.DataFrame]], planned: dict[str, int], start_s: float,
    events: list[Event], limits: dict[str, tuple[float, float, float]] | None = None,
) -> tuple[RunStats, reference_stats.RunStats]:  # fmt: skip
    new = RunStats(planned, start_s, limits)
    old = reference_stats.RunStats(planned, start_s, limits)
    for time_s, frame in steps:
        new.add_step(time_s, {c: frame[c].to_numpy() for c in frame.columns})
        clean = frame.astype(object).where(frame.notna(), None)
        old.add_step(time_s, clean.to_dict("records"))
    new.add_events(events)
    old.add_events(events)
    return new, old


def same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b) and type(a) is type(b)


def assert_same_summaries(new: RunStats, old: reference_stats.RunStats) -> None:
    assert same(new.vehicle_summaries(), old.vehicle_summaries())
    assert same(new.followers(), old.followers())
    assert same(new.platoon_summaries(), old.platoon_summaries())


cell = st.one_of(st.none(), st.floats(-50.0, 50.0, allow_nan=False))


@st.composite
def tables(draw: st.DrawFn) -> tuple[list[tuple[float, pd.DataFrame]], float, list[Event]]:
    n_vehicles = draw(st.integers(1, 6))
    n_steps = draw(st.integers(1, 25))
    steps = []
    for k in range(n_steps):
        present = draw(st.lists(st.booleans(), min_size=n_vehicles, max_size=n_vehicles))
        rows = []
        for i in range(n_vehicles):
            if not present[i]:
                continue
            platoon = "a" if i < 3 else "b"
            row: dict[str, Any] = dict(
                vehicle_id=f"{platoon}.{i}", platoon_id=platoon, member_index=i % 3,
                role="leader" if i % 3 == 0 else "follower",
                predecessor_id=draw(st.sampled_from([None, f"{platoon}.{i - 1}", "gone"]))
                if i % 3 else None,
                predecessor_rays=draw(st.one_of(st.none(), st.integers(0, 4))),
                predecessor_in_view=draw(st.one_of(st.none(), st.integers(0, 1))),
                supervisor=draw(st.sampled_from([None, "signal", "emergency"])),
            )  # fmt: skip
            for c in NUMERIC:
                row[c] = draw(cell)
            rows.append(row)
        frame = pd.DataFrame(rows, columns=["vehicle_id", "platoon_id", "member_index",
                                            "role", "predecessor_id", "predecessor_rays",
                                            "predecessor_in_view", "supervisor",
                                            *NUMERIC])  # fmt: skip
        steps.append((round(k * 0.1, 6), frame))
    start_s = draw(st.sampled_from([0.0, 0.5, 1.0]))
    kinds = [EventKind.COLLISION, EventKind.SPLIT, EventKind.CUT_IN, EventKind.RED_LIGHT,
             EventKind.EMERGENCY_BRAKING]  # fmt: skip
    events = [Event(0.1, kind, "a.1", "a.0", "a", "", "a.1") for kind in draw(st.lists(
        st.sampled_from(kinds), max_size=4))]  # fmt: skip
    return steps, start_s, events


@settings(max_examples=150, deadline=None)
@given(tables(), st.booleans())
def test_random_tables_give_the_same_summaries(case, with_plan):
    steps, start_s, events = case
    planned = {"a": 3} if with_plan else {}
    limits = {"a": (10.0, 20.0, 40.0)} if with_plan else None  # some cells at the limits
    new, old = feed_both(steps, planned, start_s, events, limits)
    assert_same_summaries(new, old)


@pytest.fixture(scope="module")
def platoon_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The urban platoon scenario to 100 s: 60 s of laser followers among traffic."""
    plan = load_plan(REPO / "scenarios" / "urban_platoon.yaml", end_s=100.0)
    return run(plan, out_dir=tmp_path_factory.mktemp("stats") / "out").directory


@pytest.mark.slow  # `pytest -m "not slow"` leaves it out (the random tables stay in)
def test_a_recorded_run_gives_the_same_summaries(platoon_run):
    traj = pd.read_csv(platoon_run / "trajectories.csv")
    assert traj["predecessor_id"].notna().any()
    steps = [(t, frame.reset_index(drop=True)) for t, frame in traj.groupby("time_s")]
    new, old = feed_both(steps, {}, 50.0, [])
    assert any(v["in_view_share"] for v in new.vehicle_summaries())
    assert_same_summaries(new, old)
    # and the table path of summarise_trajectories sees the same columns
    via_table = RunStats({}, 50.0)
    for time_s, columns in table_steps(traj):
        via_table.add_step(time_s, columns)
    assert same(via_table.vehicle_summaries(), new.vehicle_summaries())


def test_a_vehicle_twice_in_one_step_is_refused():
    stats = RunStats()
    twice = {"vehicle_id": np.array(["a", "a"]), "platoon_id": np.array(["p", "p"])}
    try:
        stats.add_step(0.0, twice)
    except ValueError as exc:
        assert "more than one row" in str(exc)
    else:
        raise AssertionError("accepted a vehicle twice in one step")
