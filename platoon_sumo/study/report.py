"""A study's figures: each collected metric against each varied parameter, one line per
combination of the other parameters, mean and standard deviation over repetitions;
PNGs and a Markdown page in the study folder (or `out`)."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from platoon_sumo.errors import PlatoonSumoError


def write_study_report(folder: str | Path, out: str | Path | None = None) -> Path:
    """Figures and report.md of a finished study folder; returns the Markdown file."""
    folder = Path(folder)
    table_path = folder / "study.csv"
    if not table_path.is_file():
        raise PlatoonSumoError(f"{folder}: no study.csv (not a finished study folder)")
    spec = yaml.safe_load((folder / "study.yaml").read_text(encoding="utf-8"))
    parameters = list((spec.get("parameters") or {}).keys())
    metrics = list(spec["metrics"])
    table = pd.read_csv(table_path)
    target = Path(out) if out else folder / "report"
    target.mkdir(parents=True, exist_ok=True)
    done = table[table.status == "complete"]
    lines = [
        f"# Study {folder.name}",
        "",
        f"{len(table)} runs, {len(done)} complete, {len(table) - len(done)} failed or not "
        f"run; parameters: {', '.join(f'`{p}`' for p in parameters) or 'none'}; "
        f"repetitions: {spec.get('repetitions', 1)}. Points: mean over the completed "
        "repetitions; bars: their standard deviation.",
        "",
    ]
    for metric in metrics:
        lines.append(f"## `{metric}`")
        lines.append("")
        for parameter in parameters or [None]:
            name = _figure(done, metric, parameter, parameters, target)
            lines.append(f"![{metric} against {parameter}]({name})")
        lines.append("")
    failed = table[table.status != "complete"]
    if len(failed):
        lines += ["## Runs that did not complete", "", "| run | status | reason |", "|---|---|---|"]
        lines += [f"| {r.run_id} | {r.status} | {r.reason} |" for r in failed.itertuples()]
    path = target / "report.md"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _figure(
    table: pd.DataFrame, metric: str, parameter: str | None, parameters: Sequence[str], out: Path
) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    values = pd.to_numeric(table[metric], errors="coerce") if metric in table else None
    if values is None or values.dropna().empty or parameter is None:
        ax.text(0.5, 0.5, "no data", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
    else:
        data = table.assign(_y=values)
        others = [p for p in parameters if p != parameter]
        groups = data.groupby(others, sort=False, dropna=False) if others else [((), data)]
        order = list(dict.fromkeys(data[parameter]))
        numeric = all(isinstance(v, int | float) for v in order)
        for key, rows in groups:
            stats = rows.groupby(parameter, sort=False)["_y"].agg(["mean", "std"])
            stats = stats.reindex([v for v in order if v in stats.index])
            x = list(stats.index) if numeric else [order.index(v) for v in stats.index]
            label = _label(others, key)
            ax.errorbar(x, stats["mean"], yerr=stats["std"].fillna(0.0), marker="o",
                        capsize=3, label=label or None)  # fmt: skip
        if not numeric:
            ax.set_xticks(range(len(order)), [str(v) for v in order])
        ax.set_xlabel(parameter)
        ax.set_ylabel(metric)
        ax.grid(alpha=0.3)
        if others:
            ax.legend(fontsize=8)
    fig.tight_layout()
    name = f"{_slug(metric)}__{_slug(parameter or 'none')}.png"
    fig.savefig(out / name, dpi=100)
    plt.close(fig)
    return name


def _label(names: Sequence[str], key: Any) -> str:
    values = key if isinstance(key, tuple) else (key,)
    return ", ".join(f"{n.split('.')[-1]}={v}" for n, v in zip(names, values, strict=False))


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_")
