"""The run's summary tables (vehicles.csv, platoons.csv) and summary.json sections.

The frequency responses of string stability are estimated here, after the run, from the
trajectory table (`frequency_responses`): they need whole series, which the online
statistics do not keep (`platoon_sumo.metrics.string_stability` says why). Only the
platoons judged stable or unstable from their l2 gains are read (`NEEDS_RESPONSE`), and
only the columns the estimate needs: memory grows with those platoons' rows.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from platoon_sumo.metrics import string_stability as ss
from platoon_sumo.metrics.stats import V2V_COLUMNS, RunStats
from platoon_sumo.metrics.sumo_outputs import join_trips, trip_metrics

#: The trajectory columns the frequency responses read.
SERIES_COLUMNS = ("time_s", "vehicle_id", "platoon_id", "member_index", "predecessor_id",
                  "speed_mps", "accel_mps2", "spacing_error_m")  # fmt: skip
#: The signals compared from member to member: (name, trajectory column).
SIGNALS = (("speed", "speed_mps"), ("accel", "accel_mps2"), ("spacing_error", "spacing_error_m"))
#: The verdicts the frequency response refines (a stable platoon may amplify at a
#: frequency its l2 gains average away). Split and undisturbed platoons are not judged by
#: gains; saturated ones (most platoons in traffic: signals, the supervisor) keep their
#: l2 gains, so that long traffic runs are not read back.
NEEDS_RESPONSE = (ss.STABLE, ss.UNSTABLE, ss.MARGINAL)
#: Per-follower fields the frequency responses add to vehicles.csv.
RESPONSE_FIELDS = ("frequency_gain", "frequency_gain_hz", "spacing_error_l2_ratio",
                   "spacing_error_linf_ratio")  # fmt: skip


def summary_tables(
    stats: RunStats, trips: pd.DataFrame, trajectories: Path | None = None
) -> tuple[list[dict[str, Any]], list[dict[str, Any]], dict[str, dict[str, Any]]]:
    """(vehicles, platoons, string stability) rows: our metrics with SUMO's travel and
    emission figures, and the frequency responses (`summary.json` → `string_stability`)
    from the `trajectories` table, when written, of the platoons in `NEEDS_RESPONSE`."""
    vehicles = stats.vehicle_summaries()
    for v in vehicles:
        v.update(dict.fromkeys(RESPONSE_FIELDS))
    wanted = [
        p["platoon_id"]
        for p in stats.platoon_summaries(vehicles)
        if p["string_stability_verdict"] in NEEDS_RESPONSE
    ]
    responses: dict[str, dict[str, Any]] = {}
    if trajectories is not None and wanted:
        responses = frequency_responses(read_series(trajectories, wanted), stats.start_s)
    by_id = {v["vehicle_id"]: v for v in vehicles}
    for response in responses.values():
        for vid, f in response["followers"].items():
            by_id[vid].update({k: f[k] for k in RESPONSE_FIELDS})
    methods = {pid: r["method"] for pid, r in responses.items()}
    platoons = stats.platoon_summaries(vehicles, methods)
    vehicles = join_trips(vehicles, trip_metrics(trips))
    for p in platoons:
        members = [v for v in vehicles if v["platoon_id"] == p["platoon_id"]]
        times = [v["travel_time_s"] for v in members if v.get("travel_time_s") is not None]
        # math.fsum: correctly rounded, so every Python writes the same digits (the built-in
        # sum adds naively before 3.12 and compensated since)
        p["mean_travel_time_s"] = math.fsum(times) / len(times) if times else None
        for key, unit in (("fuel", "kg"), ("co2", "kg")):
            grams = [v[f"{key}_g"] for v in members if v.get(f"{key}_g") is not None]
            p[f"{key}_{unit}"] = math.fsum(grams) / 1000.0 if grams else None
    return vehicles, platoons, responses


def read_series(path: Path, platoons: Collection[str]) -> pd.DataFrame:
    """The `SERIES_COLUMNS` of these platoons' rows of a trajectory table (CSV read in
    chunks, or Parquet)."""
    wanted = set(platoons)
    columns = list(SERIES_COLUMNS)
    if path.suffix == ".parquet":
        frame = pd.read_parquet(path, columns=columns)
        return frame[frame["platoon_id"].astype(str).isin(wanted)]
    text = dict.fromkeys(("vehicle_id", "platoon_id", "predecessor_id"), str)
    chunks = pd.read_csv(path, usecols=columns, dtype=text, chunksize=200_000)
    parts = [chunk[chunk["platoon_id"].isin(wanted)] for chunk in chunks]
    return pd.concat(parts) if parts else pd.DataFrame(columns=columns)


def frequency_responses(series: pd.DataFrame, start_s: float = 0.0) -> dict[str, dict[str, Any]]:
    """{platoon: its string-stability section} from trajectory rows (`SERIES_COLUMNS`)
    in the metrics window: the leader's excitation, and per follower the gains from its
    predecessor at the excitation's frequencies (`string_stability.gains`) and the l2 and
    l∞ ratios of their spacing errors. Platoons whose leader does not excite them
    (`string_stability.excitation`) are left out."""
    window = series[series["time_s"] >= start_s - 1e-9]
    out = {}
    for pid, rows in window.groupby("platoon_id", sort=True):
        response = _platoon_response(rows)
        if response is not None:
            out[str(pid)] = response
    return out


def _platoon_response(rows: pd.DataFrame) -> dict[str, Any] | None:
    """One platoon's section (see `frequency_responses`)."""
    times = np.sort(rows["time_s"].unique())
    if len(times) < 2:
        return None
    dt = float(np.median(np.diff(times)))
    vehicles = rows["vehicle_id"].astype(str).unique()
    tables = {
        c: rows.pivot(index="time_s", columns="vehicle_id", values=c).reindex(
            index=times, columns=vehicles
        )
        for _, c in SIGNALS
    }
    followed = rows.dropna(subset=["predecessor_id"]).groupby("vehicle_id")["predecessor_id"]
    predecessor = {str(v): str(p.mode().iloc[0]) for v, p in followed}
    index = rows.groupby("vehicle_id")["member_index"].first()
    leader = str(index.idxmin())
    if leader in predecessor:
        return None
    exc = ss.excitation(_stretch(tables["speed_mps"][[leader]], dt)[:, 0], dt)
    if exc is None:
        return None
    members = sorted(vehicles, key=lambda v: index[v])
    heads = {column: _head_amplitudes(tables[column], members, dt, exc) for _, column in SIGNALS}
    followers = {}
    for vid in sorted(predecessor, key=lambda v: index[v]):
        ahead = predecessor[vid]
        if ahead not in tables["speed_mps"]:
            continue
        entry: dict[str, Any] = {"predecessor_id": ahead}
        worst: tuple[float, float | None] = (-math.inf, None)
        for name, column in SIGNALS:
            table = tables[column]
            pair = _stretch(table[[ahead, vid]], dt)
            found = ss.gains(pair[:, 0], pair[:, 1], dt, exc, heads[column]) if len(pair) else None
            entry[f"{name}_gain"] = found
            for g, f in zip(found or [], exc.frequencies_hz, strict=False):
                if g is not None and g > worst[0]:
                    worst = (g, float(f))
        entry["frequency_gain"], entry["frequency_gain_hz"] = (
            worst if worst[1] is not None else (None, None)
        )
        errors = _stretch(tables["spacing_error_m"][[ahead, vid]], dt)
        l2, linf = ss.norm_ratios(errors[:, 0], errors[:, 1]) if len(errors) else (None, None)
        entry["spacing_error_l2_ratio"], entry["spacing_error_linf_ratio"] = l2, linf
        followers[vid] = entry
    return {
        "method": exc.kind,
        "frequencies_hz": [float(f) for f in exc.frequencies_hz],
        "followers": followers,
    }


def _head_amplitudes(
    table: pd.DataFrame, members: list[str], dt: float, exc: ss.Excitation
) -> np.ndarray | None:
    """The amplitudes (`string_stability.amplitudes`) of the signal of the first member,
    in platoon order, that has it (the leader; for spacing errors the first follower)."""
    for vid in members:
        series = _stretch(table[[vid]], dt)
        if len(series):
            return ss.amplitudes(series[:, 0], dt, exc)
    return None


def _stretch(table: pd.DataFrame, dt: float) -> np.ndarray:
    """The longest run of consecutive steps (at most 1.5 dt apart) on which every column
    has a value, as an array (time x column); empty without one."""
    complete = table.dropna()
    if complete.empty:
        return np.empty((0, table.shape[1]))
    breaks = np.flatnonzero(np.diff(complete.index.to_numpy(dtype=np.float64)) > 1.5 * dt)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks + 1, [len(complete)]])
    k = int(np.argmax(ends - starts))
    return complete.iloc[starts[k] : ends[k]].to_numpy(dtype=np.float64)


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
        "mean_intact_share": math.fsum(shares) / len(shares) if shares else None,
        "splits": pick("splits", sum),
        "cut_ins": pick("cut_ins", sum),
        "fuel_kg": pick("fuel_kg", math.fsum),
        "co2_kg": pick("co2_kg", math.fsum),
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
