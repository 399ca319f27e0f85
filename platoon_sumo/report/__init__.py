"""Reports of finished runs: figures and a one-page Markdown report, and comparisons.

`write_report(results_dir)` reads a results folder (summary.json, trajectories,
vehicles.csv, scan_snapshot.npz) and writes `report/` inside it: PNG figures and
`report.md`. `write_comparison(dirs, out)` puts several runs side by side:
`comparison.csv`, `comparison.md` and overlay figures.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from platoon_sumo.errors import PlatoonSumoError
from platoon_sumo.report import animation, figures
from platoon_sumo.results import COMPLETE, FAILED, check_finished_run, claim

__all__ = ["ReportError", "load_results", "write_comparison", "write_report"]


class ReportError(PlatoonSumoError):
    """A results folder that cannot be reported on (unfinished, or without tables)."""


Warn = Callable[[str], None]


def load_results(
    directory: Path, warn: Warn | None = None
) -> tuple[dict[str, Any], pd.DataFrame, pd.DataFrame]:
    """(summary, trajectories, vehicles) of a results folder, once its manifest shows a
    finished run with every file as written (`results.check_finished_run`, whose
    warnings go to `warn`). A run in which no platoon vehicle departed has empty tables."""
    for message in check_finished_run(directory):
        if warn is not None:
            warn(message)
    summary = json.loads((directory / "summary.json").read_text(encoding="utf-8"))
    if summary.get("trajectory_format") == "parquet":
        traj = pd.read_parquet(directory / "trajectories.parquet")
    elif (directory / "trajectories.csv").is_file():
        traj = _read_csv(directory / "trajectories.csv")
    else:
        raise ReportError(f"{directory}: no trajectory table (outputs.trajectories was off)")
    return summary, traj, _read_csv(directory / "vehicles.csv")


def _read_csv(path: Path) -> pd.DataFrame:
    """A table of ours; empty (no platoon vehicle departed) when the file has no rows."""
    if not path.is_file() or path.stat().st_size == 0:
        return pd.DataFrame()
    try:
        return pd.read_csv(path)
    except pd.errors.EmptyDataError:
        return pd.DataFrame()


def _fmt(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1000 else f"{value:,.0f}"
    return str(value)


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


#: (key, label with unit) of the platoon rows shown in reports and comparisons.
PLATOON_COLUMNS = (
    ("max_rms_spacing_error_m", "RMS spacing error, worst member [m]"),
    ("max_abs_spacing_error_m", "peak spacing error [m]"),
    ("min_gap_m", "min gap [m]"),
    ("min_ttc_s", "min TTC [s]"),
    ("string_stability_verdict", "string stability"),
    ("max_frequency_gain", "frequency response, worst gain [-]"),
    ("max_frequency_gain_hz", "frequency of the worst gain [Hz]"),
    ("max_accel_l2_gain", "accel. l2 gain, max [-]"),
    ("max_spacing_error_peak_ratio", "peak spacing error ratio, max [-]"),
    ("max_saturated_share", "share of steps saturated, worst follower [-]"),
    ("max_rms_accel_mps2", "RMS accel., worst [m/s²]"),
    ("max_rms_jerk_mps3", "RMS jerk, worst [m/s³]"),
    ("max_lateral_deviation_m", "max lateral deviation [m]"),
    ("intact_share", "share of time intact [-]"),
    ("splits", "splits"),
    ("cut_ins", "cut-ins"),
    ("collisions", "collisions"),
    ("emergency_brakings", "emergency brakings"),
    ("red_light_violations", "red-light violations"),
    ("mean_travel_time_s", "mean travel time [s]"),
    ("fuel_kg", "fuel [kg]"),
    ("co2_kg", "CO2 [kg]"),
)
VEHICLE_COLUMNS = (
    ("vehicle_id", "vehicle"), ("rms_spacing_error_m", "RMS spacing err. [m]"),
    ("min_gap_m", "min gap [m]"), ("min_ttc_s", "min TTC [s]"),
    ("rms_accel_mps2", "RMS accel. [m/s²]"), ("rms_jerk_mps3", "RMS jerk [m/s³]"),
    ("accel_l2_gain", "accel. l2 gain [-]"), ("max_lateral_deviation_m", "max lat. dev. [m]"),
    ("in_view_share", "in view [-]"), ("travel_time_s", "travel time [s]"),
    ("fuel_g", "fuel [g]"), ("co2_g", "CO2 [g]"),
)  # fmt: skip
TRAFFIC_COLUMNS = (
    ("human_trips_finished", "human-driven trips finished"),
    ("human_mean_time_loss_s", "their mean time loss [s]"),
    ("human_mean_waiting_time_s", "their mean waiting time [s]"),
    ("network_mean_speed_mps", "network mean speed [m/s]"),
    ("route_edges_mean_speed_mps", "mean speed on the platoons' edges [m/s]"),
    ("route_edges_time_loss_s", "time loss on the platoons' edges [s]"),
)


def write_report(
    directory: str | Path, out: str | Path | None = None, warn: Warn | None = None
) -> Path:
    """Figures and `report.md` for one results folder; returns the report's path.

    The report folder (default `report/` inside the results) is claimed like a results
    folder: new, empty, or an earlier report of ours, which it replaces."""
    directory = Path(directory)
    summary, traj, vehicles = load_results(directory, warn)
    out_dir = Path(out) if out is not None else directory / "report"
    folder = claim(out_dir, "report")
    try:
        path = _write_report(directory, summary, traj, vehicles, out_dir)
    except BaseException:
        folder.finish(FAILED)
        raise
    folder.finish(COMPLETE)
    return path


def _write_report(
    directory: Path, summary: dict[str, Any], traj: pd.DataFrame, vehicles: pd.DataFrame,
    out_dir: Path,
) -> Path:  # fmt: skip
    net = summary.get("network_file")
    figs: list[tuple[str, Path]] = []
    if len(traj):
        net_path = Path(net) if net else None
        figs.append(
            ("Paths over the network", figures.network_map(traj, net_path, out_dir / "map.png"))
        )
    for pid in sorted(traj["platoon_id"].unique()) if len(traj) else []:
        figs.append(
            (
                f"Speed and spacing error, platoon {pid}",
                figures.spacing_and_speed(traj, pid, out_dir / f"spacing_speed_{pid}.png"),
            )
        )
        figs.append(
            (
                f"Time-space diagram, platoon {pid}",
                figures.time_space(traj, pid, out_dir / f"time_space_{pid}.png"),
            )
        )
        if len(vehicles):
            figs.append((f"String stability, platoon {pid}", figures.string_stability(
                traj, vehicles, pid, out_dir / f"string_stability_{pid}.png")))  # fmt: skip
    scan = figures.scan_snapshot(directory / "scan_snapshot.npz", out_dir / "laser_scan.png")
    scan_note = ""
    if scan is not None:
        figs.append(("Laser scan snapshot", scan))
    else:
        scan_note = ("\nNo laser-scan figure: no platoon vehicle in this run carries a sensor, "
                     "so there is no scan to draw (`scan_snapshot.npz` is absent).\n")  # fmt: skip
    strip = animation.filmstrip(directory, summary, traj, out_dir / "filmstrip.png")
    if strip is not None:
        figs.append(("Key moments (frames as `animate` draws them)", strip))
    if not len(traj):
        scan_note += ("\nNo platoon vehicle drove in this run (none departed, or the run "
                      "had no platoons), so there are no platoon figures.\n")  # fmt: skip
    text = _report_text(summary, vehicles, figs, out_dir) + scan_note
    path = out_dir / "report.md"
    path.write_text(text, encoding="utf-8")
    return path


def _report_text(
    summary: dict[str, Any], vehicles: pd.DataFrame, figs: list[tuple[str, Path]], out_dir: Path
) -> str:
    platoons = summary.get("platoons", {})
    pids = sorted(platoons)
    parts = [
        f"# Run report: {summary.get('scenario')}",
        "",
        f"Scenario `{summary.get('scenario_file')}`"
        f" (sha256 `{str(summary.get('scenario_sha256'))[:12]}`),"
        f" seed {summary.get('seed')}, {_fmt(summary.get('simulated_s'))} s simulated"
        f" ({summary.get('steps')} steps); {summary.get('versions', {}).get('sumo')},"
        f" platoon_sumo {summary.get('versions', {}).get('platoon_sumo')}."
        f" Platoon vehicles arrived {summary['platoon_vehicles']['arrived']}/"
        f"{summary['platoon_vehicles']['planned']}; collisions {summary.get('collisions')},"
        f" teleports {summary.get('teleports')}, red-light violations"
        f" {summary.get('red_light_violations')}. Quality metrics from"
        f" t = {_fmt(summary.get('metrics_start_s', 0.0))} s; definitions in docs/metrics.md.",
        "",
        "## Platoons",
        "",
        _table(
            ["metric", *pids],
            [[label, *(platoons[p].get(k) for p in pids)] for k, label in PLATOON_COLUMNS],
        ),
        "",
    ]
    if len(vehicles):
        parts += ["## Vehicles", "", _table([c[1] for c in VEHICLE_COLUMNS], [
            [row.get(k) for k, _ in VEHICLE_COLUMNS] for row in vehicles.to_dict("records")]),
            ""]  # fmt: skip
    traffic = summary.get("traffic", {})
    if traffic:
        parts += ["## Other traffic (SUMO's own outputs)", "",
                  _table(["measure", "value"], [[label, traffic.get(k)]
                                                for k, label in TRAFFIC_COLUMNS]), ""]  # fmt: skip
    parts += ["## Figures", ""]
    for title, path in figs:
        parts += [f"### {title}", "", f"![{title}]({path.relative_to(out_dir).as_posix()})", ""]
    return "\n".join(parts)


def comparison_table(
    runs: Sequence[tuple[Path, dict[str, Any]]],
) -> pd.DataFrame:
    """One row per (folder, summary): the worst platoon's figures (`overall`), the
    string-stability verdicts of its platoons, and the traffic effect."""
    rows = []
    for d, summary in runs:
        row: dict[str, Any] = {"run": d.name, "scenario": summary.get("scenario"),
                               "seed": summary.get("seed")}  # fmt: skip
        row.update(summary.get("overall", {}))
        platoons = summary.get("platoons", {})
        verdicts = {p.get("string_stability_verdict") for p in platoons.values()} - {None}
        row["string_stability_verdict"] = ", ".join(sorted(verdicts)) if verdicts else None
        for key in ("max_spacing_error_peak_ratio", "max_frequency_gain", "collisions",
                    "emergency_brakings", "mean_travel_time_s"):  # fmt: skip
            values = [p.get(key) for p in platoons.values() if p.get(key) is not None]
            if key == "mean_travel_time_s":
                row[key] = math.fsum(values) / len(values) if values else None
            else:
                row[key] = max(values) if values else None
        for key, _ in TRAFFIC_COLUMNS:
            row[key] = summary.get("traffic", {}).get(key)
        rows.append(row)
    return pd.DataFrame(rows)


def write_comparison(
    directories: Sequence[str | Path], out: str | Path, warn: Warn | None = None
) -> Path:
    """comparison.csv, comparison.md and overlay figures of several runs in `out`.

    Every run is checked and read before anything is written; `out` is claimed like a
    results folder (new, empty, or an earlier comparison of ours)."""
    dirs = [Path(d) for d in directories]
    names = [d.name for d in dirs]
    if len(set(names)) != len(names):
        dirs_named = [Path(f"{d.parent.name}_{d.name}") for d in dirs]
        names = [d.name for d in dirs_named]
    loaded = [load_results(d, warn) for d in dirs]
    out_dir = Path(out)
    folder = claim(out_dir, "comparison")
    try:
        path = _write_comparison(dirs, names, loaded, out_dir)
    except BaseException:
        folder.finish(FAILED)
        raise
    folder.finish(COMPLETE)
    return path


def _write_comparison(
    dirs: list[Path], names: list[str],
    loaded: list[tuple[dict[str, Any], pd.DataFrame, pd.DataFrame]], out_dir: Path,
) -> Path:  # fmt: skip
    table = comparison_table([(d, s) for d, (s, _, _) in zip(dirs, loaded, strict=True)])
    table["run"] = names
    table.to_csv(out_dir / "comparison.csv", index=False)
    runs = [(name, t, v) for name, (_, t, v) in zip(names, loaded, strict=True)]
    bars = figures.compare_bars(table, (
        ("max_rms_spacing_error_m", "RMS spacing error,\nworst member [m]"),
        ("min_gap_m", "min gap [m]"), ("max_accel_l2_gain", "accel. l2 gain, max [-]"),
        ("max_rms_accel_mps2", "RMS accel., worst [m/s²]")),
        out_dir / "compare_metrics.png")  # fmt: skip
    along = figures.compare_along([(n, v) for n, _, v in runs if len(v)],
                                  out_dir / "compare_along_platoon.png")  # fmt: skip
    speeds = figures.compare_speeds([(n, t) for n, t, _ in runs if len(t)],
                                    out_dir / "compare_speeds.png")  # fmt: skip
    labels = {k: label for k, label in PLATOON_COLUMNS + TRAFFIC_COLUMNS}
    labels["mean_intact_share"] = "share of time intact, mean [-]"
    keys = [c for c in table.columns if c not in ("run",)]
    md = ["# Run comparison", "",
          _table(["metric", *names], [[labels.get(k, k), *table[k].tolist()] for k in keys]),
          "", "Per run: the worst platoon (`overall` in summary.json); definitions in "
          "docs/metrics.md.", ""]  # fmt: skip
    for title, path in (("Metrics", bars), ("Along the platoon", along), ("Speeds", speeds)):
        md += [f"## {title}", "", f"![{title}]({path.name})", ""]
    path = out_dir / "comparison.md"
    path.write_text("\n".join(md), encoding="utf-8")
    return path
