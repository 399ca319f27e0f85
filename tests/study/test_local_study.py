"""Issue 14 acceptance on a local Dask cluster: the table, its aggregates, failures,
determinism across worker counts, and resuming an interrupted study."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from platoon_sumo.cli import main
from platoon_sumo.study import run_study
from platoon_sumo.study.table import unknown_metrics
from tests.study.conftest import METRICS, PARAMETERS, scenario, write_study

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out


def _oracle(run_dir: Path) -> dict[str, float]:
    """The metrics read straight from a run's own files."""
    summary = json.loads((run_dir / "summary.json").read_text())
    platoons = pd.read_csv(run_dir / "platoons.csv")
    vehicles = pd.read_csv(run_dir / "vehicles.csv")
    return {
        METRICS[0]: summary["overall"]["min_gap_m"],
        METRICS[1]: summary["traffic"]["network_mean_speed_mps"],
        METRICS[2]: platoons["max_abs_spacing_error_m"].max(),
        METRICS[3]: vehicles["min_gap_m"].min(),
    }


@pytest.fixture(scope="module")
def two_workers(tmp_path_factory: pytest.TempPathFactory):
    folder = tmp_path_factory.mktemp("study")
    return run_study(write_study(folder), folder / "out", workers=2)


def test_one_row_per_run_with_its_parameters_seed_and_metrics(two_workers):
    table = two_workers.table
    assert len(table) == 8 and (table.status == "complete").all()
    assert set(PARAMETERS) <= set(table.columns) and set(METRICS) <= set(table.columns)
    combos = table[list(PARAMETERS)].drop_duplicates()
    assert len(combos) == 4 and table.groupby(list(PARAMETERS)).size().eq(2).all()
    assert table.seed.nunique() == 2  # a seed per repetition, shared by every combination
    for row in table.to_dict("records"):
        expected = _oracle(two_workers.folder / "runs" / row["run_id"])
        for metric in METRICS:
            assert row[metric] == pytest.approx(expected[metric]), (row["run_id"], metric)
    # the repetitions differ (the seed drives the traffic)
    assert table[METRICS[1]].nunique() > 1


def test_aggregates_over_repetitions(two_workers):
    table, agg = two_workers.table, two_workers.aggregate
    assert len(agg) == 4
    for row in agg.to_dict("records"):
        mine = table
        for key in PARAMETERS:
            mine = mine[mine[key] == row[key]]
        for metric in METRICS:
            values = mine[metric].astype(float)
            assert row[f"{metric}_mean"] == pytest.approx(values.mean())
            assert row[f"{metric}_std"] == pytest.approx(values.std(), nan_ok=True)
            assert row[f"{metric}_min"] == values.min() and row[f"{metric}_max"] == values.max()
            assert row[f"{metric}_count"] == 2


def test_tables_written_for_pandas(two_workers):
    folder = two_workers.folder
    csv, parquet = pd.read_csv(folder / "study.csv"), pd.read_parquet(folder / "study.parquet")
    assert len(csv) == len(parquet) == 8 and list(csv.columns) == list(parquet.columns)
    assert len(pd.read_csv(folder / "aggregate.csv")) == 4


def test_a_misspelt_metric_is_named_with_a_suggestion(two_workers):
    run_dirs = [two_workers.folder / "runs" / rid for rid in two_workers.table.run_id]
    assert unknown_metrics(run_dirs, METRICS) == []
    (message,) = unknown_metrics(run_dirs, ["vehicles.min_gapp_m:min"])
    assert "no run's vehicles.csv has 'min_gapp_m'" in message
    assert "did you mean 'min_gap_m'" in message
    (message,) = unknown_metrics(run_dirs, ["summary.overall.min_gap"])
    assert "no run's summary.json has 'overall.min_gap'" in message and "'min_gap_m'" in message


def test_study_report_draws_each_metric_against_each_parameter(two_workers, tmp_path):
    assert main(["study-report", str(two_workers.folder), "--out", str(tmp_path / "r")]) == 0
    pngs = sorted((tmp_path / "r").glob("*.png"))
    assert len(pngs) == len(METRICS) * len(PARAMETERS)
    text = (tmp_path / "r" / "report.md").read_text()
    assert "8 runs, 8 complete" in text and all(f"]({p.name})" in text for p in pngs)


def test_same_study_same_table_with_one_worker(two_workers, tmp_path):
    again = run_study(write_study(tmp_path), tmp_path / "out", workers=1)
    columns = [c for c in two_workers.table.columns if c != "wall_s"]
    pd.testing.assert_frame_equal(two_workers.table[columns], again.table[columns])


def test_a_failing_run_is_a_failed_row_and_the_others_complete(tmp_path, capfd, plugins_everywhere):
    base = scenario()
    base["platoons"][0]["leader"] = {"type": "failing_controller:FailsAt", "params": {}}
    base["platoons"][0]["members"] = 1
    study = write_study(
        tmp_path, base=base, repetitions=1,
        parameters={"platoons[0].leader.params.fail_at_s": [5.0, 1000.0]},
        metrics=["summary.overall.min_gap_m", "vehicles.steps:max"],
    )  # fmt: skip
    code = main(["study", str(study), "--out", str(tmp_path / "out"), "--workers", "2"])
    _, err = capfd.readouterr()
    assert code == 1
    table = pd.read_csv(tmp_path / "out" / "study.csv")
    failed = table[table["platoons[0].leader.params.fail_at_s"] == 5.0].iloc[0]
    done = table[table["platoons[0].leader.params.fail_at_s"] == 1000.0].iloc[0]
    assert failed.status == "failed" and "ZeroDivisionError" in failed.reason
    assert "failing_controller.FailsAt" in failed.reason and "t=5.0" in failed.reason
    assert np.isnan(failed["vehicles.steps:max"])
    assert done.status == "complete" and done["vehicles.steps:max"] > 0
    assert f"failed: run {failed.run_id}: " in err and "Traceback" not in err


def test_an_invalid_combination_is_reported_before_any_run(tmp_path, capfd):
    study = write_study(
        tmp_path, parameters={"platoons[0].follower.params.time_gap_s": [1.0, -1.0]}
    )
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    _, err = capfd.readouterr()
    (line,) = err.strip().splitlines()[-1:]
    assert line.startswith(f"error: {study}: parameters: run ")
    assert "time_gap_s=-1.0" in line and "time_gap_s" in line
    assert not (tmp_path / "out" / "runs").exists()


def test_an_interrupted_study_resumes_with_the_missing_runs_only(tmp_path):
    study = write_study(tmp_path)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "platoon_sumo.cli", "study", str(study), "--out", str(out),
           "--workers", "1", "--quiet"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    outcomes = out / "outcomes"
    deadline = time.monotonic() + 300
    while proc.poll() is None and time.monotonic() < deadline:
        if outcomes.is_dir() and len(list(outcomes.glob("*.json"))) >= 2:
            break
        time.sleep(0.2)
    assert proc.poll() is None, proc.communicate()
    os.kill(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err.decode()
    finished = {p.stem for p in outcomes.glob("*.json")}
    assert 2 <= len(finished) < 8
    result = run_study(study, out, workers=1)
    assert set(result.ran).isdisjoint(finished) and len(result.ran) == 8 - len(finished)
    assert (result.table.status == "complete").all()
