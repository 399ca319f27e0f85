"""The run's summary tables (vehicles.csv, platoons.csv) and summary.json sections."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from platoon_sumo.metrics.stats import V2V_COLUMNS, RunStats
from platoon_sumo.metrics.sumo_outputs import join_trips, trip_metrics


def summary_tables(
    stats: RunStats, trips: pd.DataFrame
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(vehicles, platoons) rows: our metrics with SUMO's travel and emission figures."""
    vehicles = join_trips(stats.vehicle_summaries(), trip_metrics(trips))
    platoons = stats.platoon_summaries()
    for p in platoons:
        members = [v for v in vehicles if v["platoon_id"] == p["platoon_id"]]
        times = [v["travel_time_s"] for v in members if v.get("travel_time_s") is not None]
        p["mean_travel_time_s"] = sum(times) / len(times) if times else None
        for key, unit in (("fuel", "kg"), ("co2", "kg")):
            grams = [v[f"{key}_g"] for v in members if v.get(f"{key}_g") is not None]
            p[f"{key}_{unit}"] = sum(grams) / 1000.0 if grams else None
    return vehicles, platoons


def overall(platoons: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Run-level figures over all platoons (worst case or total)."""

    def pick(key: str, fn: Any) -> Any:
        values = [p[key] for p in platoons if p.get(key) is not None]
        return fn(values) if values else None

    shares = [p["intact_share"] for p in platoons if p.get("intact_share") is not None]
    return {
        "min_gap_m": pick("min_gap_m", min),
        "min_ttc_s": pick("min_ttc_s", min),
        "max_rms_spacing_error_m": pick("max_rms_spacing_error_m", max),
        "max_abs_spacing_error_m": pick("max_abs_spacing_error_m", max),
        "max_accel_l2_gain": pick("max_accel_l2_gain", max),
        "max_rms_accel_mps2": pick("max_rms_accel_mps2", max),
        "max_rms_jerk_mps3": pick("max_rms_jerk_mps3", max),
        "mean_intact_share": sum(shares) / len(shares) if shares else None,
        "splits": pick("splits", sum),
        "cut_ins": pick("cut_ins", sum),
        "fuel_kg": pick("fuel_kg", sum),
        "co2_kg": pick("co2_kg", sum),
        **{key: pick(key, sum) for key in V2V_COLUMNS},
    }


def write_table(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """A summary table as CSV (`,`-separated, empty cell = none)."""
    if not rows:
        path.write_text("", encoding="utf-8")
        return
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def by_id(rows: Sequence[Mapping[str, Any]], key: str) -> dict[str, dict[str, Any]]:
    """{row[key]: the row without key}, for summary.json."""
    return {str(r[key]): {k: v for k, v in r.items() if k != key} for r in rows}
