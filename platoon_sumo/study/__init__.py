"""Studies: parameter sweeps and repetitions of a scenario on Dask, one table out.

`run_study` loads a study file (`spec`), expands and checks every run before the first
starts (`expand`), runs the missing ones on a local cluster or a scheduler (`execute`)
and writes the tables (`table`) into the study folder:

    STUDY_DIR/
      study.yaml            the study file as run
      scenarios/<id>.yaml   each run's scenario (values, seed, absolute paths)
      runs/<id>/            each run's results folder
      outcomes/<id>.json    each run's status, failure reason and wall time
      study.csv, study.parquet   one row per run (Parquet with the parquet extra)
      aggregate.csv         mean, std, min, max, count over repetitions
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from platoon_sumo.results import COMPLETE, FAILED, open_study_folder
from platoon_sumo.study.execute import Outcome, execute
from platoon_sumo.study.expand import expand, write_scenarios
from platoon_sumo.study.spec import Study, load_study
from platoon_sumo.study.table import aggregate, study_table, unknown_metrics

__all__ = ["StudyResult", "load_study", "run_study"]


@dataclass(frozen=True)
class StudyResult:
    folder: Path
    table: pd.DataFrame
    aggregate: pd.DataFrame
    ran: tuple[str, ...]
    """Run ids executed this time (the others were finished before)."""
    warnings: tuple[str, ...] = ()
    """Metrics no finished run has (misspelt keys or columns)."""


def run_study(
    path: str | Path,
    out: str | Path | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Callable[[int, int, int, int], None] | None = None,
) -> StudyResult:
    """Run (or resume) the study at `path` into `out` (default: results/<study name>)."""
    study = load_study(path)
    runs = expand(study)
    folder = Path(out or Path("results") / study.name).resolve()
    with tempfile.TemporaryDirectory(prefix="platoon_study_") as tmp:
        checked = write_scenarios(study, runs, Path(tmp))  # every run, before any starts
        owned = open_study_folder(folder, study.sha256)
        (folder / "scenarios").mkdir(exist_ok=True)
        scenarios = {rid: folder / "scenarios" / p.name for rid, p in checked.items()}
        for rid, p in checked.items():
            shutil.copyfile(p, scenarios[rid])
    status = FAILED
    try:
        (folder / "study.yaml").write_text(study.text, encoding="utf-8")
        run_dirs = {r.run_id: folder / "runs" / r.run_id for r in runs}
        outcomes = {r.run_id: o for r in runs if (o := _read(folder, r.run_id)) is not None}
        todo = {
            rid: (scenarios[rid], run_dirs[rid])
            for rid in dict.fromkeys(r.run_id for r in runs)
            if rid not in outcomes or outcomes[rid].status != COMPLETE
        }
        if todo:
            outcomes.update(
                execute(todo, lambda rid, o: _write(folder, rid, o), workers, scheduler, progress)
            )
        table = study_table(runs, outcomes, run_dirs, study.config.metrics)
        summary = aggregate(table, list(study.values), study.config.metrics)
        table.to_csv(folder / "study.csv", index=False)
        table.to_parquet(folder / "study.parquet", index=False)
        summary.to_csv(folder / "aggregate.csv", index=False)
        finished = [run_dirs[rid] for rid in table.run_id[table.status == COMPLETE]]
        warnings = unknown_metrics(finished, study.config.metrics) if finished else []
        status = COMPLETE
        return StudyResult(folder, table, summary, tuple(todo), tuple(warnings))
    finally:
        owned.finish(status)


def _read(folder: Path, run_id: str) -> Outcome | None:
    try:
        data = json.loads((folder / "outcomes" / f"{run_id}.json").read_text(encoding="utf-8"))
        return Outcome(str(data["status"]), str(data.get("reason", "")), float(data["wall_s"]))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _write(folder: Path, run_id: str, outcome: Outcome) -> None:
    path = folder / "outcomes" / f"{run_id}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {"status": outcome.status, "reason": outcome.reason, "wall_s": outcome.wall_s}
    path.write_text(json.dumps(data) + "\n", encoding="utf-8")


def describe(study: Study) -> str:
    """One line: how many runs, over what."""
    keys = ", ".join(study.values) or "no parameter"
    return f"{study.name}: {len(expand(study))} runs ({keys}; {study.config.repetitions} each)"
