"""A study's tidy table (one row per run: parameters, seed, status, wall time, metrics)
and its aggregate over repetitions."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from platoon_sumo.errors import did_you_mean
from platoon_sumo.study.execute import Outcome
from platoon_sumo.study.expand import StudyRun
from platoon_sumo.study.spec import Metric, parse_metric

#: The table's columns before the parameters and metrics.
RUN_COLUMNS = ("run_id", "repetition", "seed", "status", "reason", "wall_s")
AGGREGATES = ("mean", "std", "min", "max", "count")


def run_metrics(run_dir: Path, metrics: Sequence[str]) -> dict[str, Any]:
    """The named metrics of one finished run (None where a run has no such value)."""
    summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    tables: dict[str, pd.DataFrame] = {}
    out = {}
    for text in metrics:
        metric = parse_metric(text, "metrics")
        if metric.source == "summary":
            out[text] = _dotted(summary, metric.key)
            continue
        if metric.source not in tables:
            tables[metric.source] = _read_table(run_dir / f"{metric.source}.csv")
        out[text] = _reduce(tables[metric.source], metric)
    return out


def unknown_metrics(run_dirs: Sequence[Path], metrics: Sequence[str]) -> list[str]:
    """Messages for metrics no finished run's files have (a misspelt key or column),
    with a did-you-mean from what the runs do have. A table without rows (a run with no
    platoon vehicle) has no columns: another run must show the metric."""
    summaries = [json.loads((d / "summary.json").read_text(encoding="utf-8")) for d in run_dirs]
    out = []
    for text in metrics:
        metric = parse_metric(text, "metrics")
        names: set[str] = set()
        for run_dir, summary in zip(run_dirs, summaries, strict=True):
            if metric.source == "summary":
                *parents, last = metric.key.split(".")
                node: Any = summary
                for part in parents:
                    node = node.get(part) if isinstance(node, Mapping) else None
                have = set(node) if isinstance(node, Mapping) else set()
                wanted = last
            else:
                have = set(_read_table(run_dir / f"{metric.source}.csv").columns)
                wanted = metric.key
            if wanted in have:
                break
            names |= have
        else:
            where = "summary.json" if metric.source == "summary" else f"{metric.source}.csv"
            hint = did_you_mean(metric.key.split(".")[-1], sorted(names))
            out.append(
                f"metric '{text}': no run's {where} has '{metric.key}'"
                + (f" ({hint})" if hint else "")
            )
    return out


def _read_table(path: Path) -> pd.DataFrame:
    """A run's summary table; empty (no columns) when the run had no platoon vehicle."""
    try:
        return pd.read_csv(path)
    except pd.errors.EmptyDataError:
        return pd.DataFrame()


def _dotted(data: Any, key: str) -> Any:
    for part in key.split("."):
        if not isinstance(data, Mapping) or part not in data:
            return None
        data = data[part]
    return data if isinstance(data, int | float | str | bool) or data is None else None


def _reduce(table: pd.DataFrame, metric: Metric) -> float | None:
    if metric.key not in table.columns:
        return None
    column = pd.to_numeric(table[metric.key], errors="coerce").dropna()
    if metric.reducer == "count":
        return float(len(column))
    if column.empty:
        return None
    value = float(getattr(column, metric.reducer)())
    return value if math.isfinite(value) else None


def study_table(
    runs: Sequence[StudyRun],
    outcomes: Mapping[str, Outcome],
    run_dirs: Mapping[str, Path],
    metrics: Sequence[str],
) -> pd.DataFrame:
    """One row per run in study order; metrics empty for runs that did not complete."""
    rows = []
    for run in runs:
        outcome = outcomes.get(run.run_id) or Outcome("not run")
        row: dict[str, Any] = {
            "run_id": run.run_id, "repetition": run.repetition, "seed": run.seed,
            "status": outcome.status, "reason": outcome.reason, "wall_s": outcome.wall_s,
            **run.values,
        }  # fmt: skip
        values = (
            run_metrics(run_dirs[run.run_id], metrics)
            if outcome.status == "complete"
            else dict.fromkeys(metrics)
        )
        rows.append(row | values)
    columns = [*RUN_COLUMNS, *(runs[0].values if runs else ()), *metrics]
    return pd.DataFrame(rows, columns=columns)


def aggregate(
    table: pd.DataFrame, parameters: Sequence[str], metrics: Sequence[str]
) -> pd.DataFrame:
    """Mean, std, min, max and count of each metric over the completed repetitions of
    each parameter combination (columns `<metric>_<statistic>`)."""
    done = table[table.status == "complete"]
    numeric = done[list(metrics)].apply(pd.to_numeric, errors="coerce")
    frame = pd.concat([done[list(parameters)], numeric], axis=1)
    if parameters:
        grouped = frame.groupby(list(parameters), sort=False, dropna=False)[list(metrics)]
        stats = grouped.agg(list(AGGREGATES))
        stats.columns = [f"{m}_{s}" for m, s in stats.columns]
        return stats.reset_index()
    row = {f"{m}_{s}": getattr(numeric[m], s)() for m in metrics for s in AGGREGATES}
    return pd.DataFrame([row])
