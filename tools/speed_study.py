"""Speed study of the paper's experiment: up to which leader speed does the platoon hold?

Runs `scenarios/paper_world.yaml` at increasing leader speeds, once with the paper's
follower (Algorithm 2) and once with platoon-sumo's `laser_follower`, both on the
paper's follower scan, and reports for each run whether the platoon stayed intact:
every follower kept its predecessor in its scan at every scan after first seeing it,
and no collision happened (with anything: another robot or a wall). Writes a Markdown
table, a CSV, a JSON and a PNG. The summary lists, per follower, every tested speed at
which the platoon stayed intact and the highest of them; intact speeds need not be
contiguous (see docs/paper.md, "Speed study", for a failure at the lowest speed only).

With `--arc-times`, only the paper's follower runs, once per `arc_time_s` (the constant
the paper does not give: speed = arc / `arc_time_s`) and leader speed, everything else
as in the scenario; the results go to `arc_time_study.{md,csv,json,png}` in OUT, with
the highest intact speed per `arc_time_s` beside `range_max / arc_time_s`, about the
most the follower can command while it still sees its predecessor.

    python tools/speed_study.py                    # full study (a few minutes on 2 cores)
    python tools/speed_study.py --speeds 0.1 0.3 --lap-fraction 0.25 --out /tmp/study
    python tools/speed_study.py --arc-times 1 2 4 8 --speeds 0.1 0.2 --lap-fraction 0.25
    python tools/speed_study.py --replot           # redo tables/PNGs from OUT/*.json
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import multiprocessing
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "paper_world.yaml"
DEFAULT_SPEEDS = (0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.6, 0.8)
LAP_M = 43.0  # one lap of loop_outer in the right lane (networks/paper_world/README.md)
STUDY = "speed_study"  # file stem of the follower comparison
ARC_STUDY = "arc_time_study"  # file stem of the paper follower's arc_time_s sweep

#: The followers compared, each with the parameters it needs at robot scale; None: as
#: configured in the scenario (the paper follower with the reading of docs/paper.md).
FOLLOWERS: dict[str, dict[str, Any] | None] = {
    "paper_follower": None,
    "laser_follower": {
        "type": "laser_follower",
        "params": {  # robot scale, as documented in platoon_sumo/control/laser_follower.py
            "standstill_gap_m": 0.35,
            "time_gap_s": 0.6,
            "min_gap_m": 0.15,
            "comfort_decel_mps2": 0.5,
            "lookahead_min_m": 0.3,
            "trail_spacing_m": 0.02,
            "perception": {"break_abs_m": 0.03, "corner_abs_m": 0.01},
            "tracker": {
                "accel_noise_mps2": 1.0,
                "meas_noise_m": 0.01,
                "start_range_max_m": 1.5,
                "start_lateral_m": 0.2,
                "init_speed_std_mps": 0.3,
            },
            "fallback": {"lookahead_min_m": 0.3, "comfort_decel_mps2": 0.5},
        },
    },
}


@dataclass(frozen=True)
class Case:
    follower: str
    speed_mps: float
    end_s: float
    arc_time_s: float | None = None  # the paper follower's arc_time_s; None: the scenario's


def scenario_for(case: Case, base: dict[str, Any]) -> dict[str, Any]:
    """The paper scenario with the leader's speed and the follower under test."""
    data = yaml.safe_load(yaml.safe_dump(base))  # deep copy
    platoon = data["platoons"][0]
    leader = platoon["leader"]
    leader.setdefault("params", {})["linear_mps"] = case.speed_mps
    chosen = FOLLOWERS[case.follower]
    if chosen is not None:
        platoon["follower"] = {**chosen, "sensor": platoon["follower"]["sensor"]}
    if case.arc_time_s is not None:
        if platoon["follower"].get("type") != "paper_follower":
            raise ValueError("arc_time_s is a parameter of paper_follower only")
        platoon["follower"].setdefault("params", {})["arc_time_s"] = case.arc_time_s
    data["simulation"]["end_s"] = case.end_s
    for key in ("net_file",):
        data["network"][key] = str((SCENARIO.parent / data["network"][key]).resolve())
    data["network"]["additional_files"] = [
        str((SCENARIO.parent / f).resolve()) for f in data["network"].get("additional_files", [])
    ]
    data.pop("outputs", None)
    return data


def run_case(case: Case, base: dict[str, Any]) -> dict[str, Any]:
    """One run in this (fresh) process: libsumo allows one simulation per process."""
    from platoon_sumo.runner import load_plan, run

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scenario.yaml"
        path.write_text(yaml.safe_dump(scenario_for(case, base), sort_keys=False))
        summary = run(load_plan(path), out_dir=Path(tmp) / "out").summary
    followers = summary["followers"].get("robots", {})
    shares = [f["in_view_share"] or 0.0 for f in followers.values()]
    lost = sum(f["lost_scans"] for f in followers.values())
    min_gap = min((f["min_gap_m"] for f in followers.values() if f["min_gap_m"] is not None),
                  default=None)  # fmt: skip
    intact = bool(followers) and lost == 0 and summary["collisions"] == 0
    lost_by = sorted(vid for vid, f in followers.items() if f["lost_scans"])
    hits = [
        f"{e['vehicle_a']}/{e['vehicle_b']}@{e['time_s']:g}s"
        for e in summary.get("collision_events", [])
    ]
    sweep = {} if case.arc_time_s is None else {"arc_time_s": case.arc_time_s}
    return {
        "follower": case.follower,
        **sweep,
        "leader_speed_mps": case.speed_mps,
        "simulated_s": summary["simulated_s"],
        "intact": intact,
        "min_in_view_share": min(shares) if shares else 0.0,
        "lost_scans": lost,
        "collisions": summary["collisions"],
        "min_gap_m": min_gap,
        "lost_followers": " ".join(lost_by),
        "collision_events": " ".join(hits),
    }


def plan_cases(
    speeds: Sequence[float],
    followers: Sequence[str],
    lap_fraction: float,
    arc_times: Sequence[float] | None = None,
) -> list[Case]:
    """One run per follower and speed or, given ``arc_times``, one run of the paper's
    follower per ``arc_time_s`` and speed."""
    variants = [(f, None) for f in followers] if arc_times is None else [
        ("paper_follower", a) for a in arc_times
    ]  # fmt: skip
    return [
        Case(f, v, end_s=round(20.0 + lap_fraction * LAP_M / v, 2), arc_time_s=a)
        for f, a in variants
        for v in speeds
    ]


def study(
    speeds: Sequence[float],
    followers: Sequence[str],
    lap_fraction: float,
    jobs: int,
    arc_times: Sequence[float] | None = None,
) -> list[dict[str, Any]]:
    base = yaml.safe_load(SCENARIO.read_text())
    cases = plan_cases(speeds, followers, lap_fraction, arc_times)
    context = multiprocessing.get_context("spawn")
    with context.Pool(processes=jobs, maxtasksperchild=1) as pool:
        pending = [pool.apply_async(run_case, (c, base)) for c in cases]
        rows = []
        for c, p in zip(cases, pending, strict=True):
            row = p.get()
            rows.append(row)
            mark = "intact" if row["intact"] else "broken"
            name = c.follower if c.arc_time_s is None else f"arc_time_s {c.arc_time_s:g}"
            print(f"{name:15s} {c.speed_mps:5.2f} m/s: {mark}", file=sys.stderr)
    return rows


def _runs(
    rows: list[dict[str, Any]], follower: str, arc_time_s: float | None
) -> list[dict[str, Any]]:
    """The rows of this follower (and, if given, of this arc_time_s)."""
    return [
        r for r in rows
        if r["follower"] == follower and (arc_time_s is None or r["arc_time_s"] == arc_time_s)
    ]  # fmt: skip


def intact_speeds(
    rows: list[dict[str, Any]], follower: str, arc_time_s: float | None = None
) -> list[float]:
    """Every tested leader speed at which the platoon with this follower stayed intact."""
    return sorted(
        float(r["leader_speed_mps"]) for r in _runs(rows, follower, arc_time_s) if r["intact"]
    )


def highest_intact(
    rows: list[dict[str, Any]], follower: str, arc_time_s: float | None = None
) -> float | None:
    """Highest tested speed at which the platoon stayed intact (None: at none)."""
    speeds = intact_speeds(rows, follower, arc_time_s)
    return speeds[-1] if speeds else None


def highest_intact_from_lowest(
    rows: list[dict[str, Any]], follower: str, arc_time_s: float | None = None
) -> float | None:
    """Highest speed such that every tested speed up to it kept the platoon intact
    (the study's former headline; None when the lowest tested speed already failed)."""
    best = None
    for row in sorted(_runs(rows, follower, arc_time_s),
                      key=lambda r: r["leader_speed_mps"]):  # fmt: skip
        if not row["intact"]:
            break
        best = float(row["leader_speed_mps"])
    return best


def _speeds_text(speeds: Sequence[float]) -> str:
    return "{" + ", ".join(f"{v:g}" for v in speeds) + "}" if speeds else "none"


def _cell(row: Any) -> str:
    state = "intact" if row["intact"] else "**lost**"
    n = int(row["collisions"])
    text = f"{state} (in view {row['min_in_view_share']:.0%}, {n} collision{'s' if n != 1 else ''}"
    events = row.get("collision_events")
    if n and isinstance(events, str) and events:
        text += f": {events}"
    return text + ")"


def _speed_grid(
    table: Any, column: str, values: Sequence[Any], headers: Sequence[str], cell: Any
) -> list[str]:
    """Markdown table: a row per leader speed, a column per value of `column` (headed
    `headers`), each cell `cell(row)` of that run, empty where it did not run."""
    lines = [
        "| leader speed [m/s] | " + " | ".join(headers) + " |",
        "|---|" + "---|" * len(values),
    ]
    for speed, group in table.groupby("leader_speed_mps"):
        cells = []
        for value in values:
            r = group[group[column] == value]
            cells.append("" if r.empty else cell(r.iloc[0]))
        lines.append(f"| {speed:g} | " + " | ".join(cells) + " |")
    return lines


def _intact_cells(speeds: Sequence[float], best: float | None, contiguous: float | None) -> str:
    """The intact speeds, the highest one and the highest with every lower one intact."""
    return (
        f"{_speeds_text(speeds)} | {'none' if best is None else f'{best:g}'} "
        f"| {'none (lowest speed lost)' if contiguous is None else f'{contiguous:g}'}"
    )


def write_outputs(rows: list[dict[str, Any]], out: Path, command: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    table = pd.DataFrame(rows).sort_values(["follower", "leader_speed_mps"])
    table.to_csv(out / f"{STUDY}.csv", index=False)
    followers = list(dict.fromkeys(r["follower"] for r in rows))
    lines = _speed_grid(table, "follower", followers, [f"`{f}`" for f in followers], _cell)
    tested = sorted({float(r["leader_speed_mps"]) for r in rows})
    speeds = {f: intact_speeds(rows, f) for f in followers}
    best = {f: highest_intact(rows, f) for f in followers}
    contiguous = {f: highest_intact_from_lowest(rows, f) for f in followers}
    lines += [
        "",
        "Intact: every follower kept >= 1 ray on its predecessor at every scan after first "
        "seeing it, and 0 collisions (robots or walls). In view: the worst follower's share "
        "of such scans.",
        "",
        f"Tested leader speeds [m/s]: {_speeds_text(tested)}",
        "",
        "| follower | intact at [m/s] | highest intact [m/s] | intact at every speed up to [m/s] |",
        "|---|---|---|---|",
    ]
    for f in followers:
        lines.append(f"| `{f}` | {_intact_cells(speeds[f], best[f], contiguous[f])} |")
    lines += ["", f"Command: `{command}`"]
    (out / f"{STUDY}.md").write_text("\n".join(lines) + "\n")
    summary = {
        "command": command,
        "intact_speeds": speeds,
        "highest_intact": best,
        "highest_intact_from_lowest": contiguous,
        "rows": rows,
    }
    (out / f"{STUDY}.json").write_text(json.dumps(summary, indent=2) + "\n")
    _plot(table, followers, out / f"{STUDY}.png", plt)


def _plot(table: Any, followers: list[str], path: Path, plt: Any) -> None:
    fig, (ax, strip) = plt.subplots(
        2, 1, figsize=(7.5, 5.2), sharex=True, height_ratios=(3, 1.2), layout="constrained"
    )
    for i, f in enumerate(followers):
        part = table[table["follower"] == f]
        x, y = part["leader_speed_mps"], part["min_in_view_share"] * 100
        color = f"C{i}"
        ax.plot(x, y, "-", color=color, alpha=0.6, label=f)
        ok, bad = part[part["intact"]], part[~part["intact"]]
        ax.plot(ok["leader_speed_mps"], ok["min_in_view_share"] * 100, "o", color=color,
                markersize=7)  # fmt: skip
        ax.plot(bad["leader_speed_mps"], bad["min_in_view_share"] * 100, "X", color=color,
                markeredgecolor="black", markersize=11)  # fmt: skip
        strip.plot(ok["leader_speed_mps"], [i] * len(ok), "o", color=color, markersize=9)
        strip.plot(bad["leader_speed_mps"], [i] * len(bad), "X", color=color,
                   markeredgecolor="black", markersize=11)  # fmt: skip
        for _, row in part[part["collisions"] > 0].iterrows():
            n = int(row["collisions"])
            label = f"{n} collision{'s' if n != 1 else ''}"
            ax.annotate(label, (row["leader_speed_mps"], row["min_in_view_share"] * 100),
                        xytext=(14, -14), textcoords="offset points", color=color,
                        fontsize=8, arrowprops={"arrowstyle": "-", "color": color})  # fmt: skip
            strip.annotate("collision", (row["leader_speed_mps"], i), xytext=(8, 5),
                           textcoords="offset points", fontsize=7, color=color)  # fmt: skip
    ax.set_ylabel("worst follower: scans with\npredecessor in view [%]")
    ax.set_title("Paper world, 5 robots: does every follower keep its predecessor?")
    ax.set_ylim(-5, 108)
    ax.grid(alpha=0.3)
    handles, _labels = ax.get_legend_handles_labels()
    marks = [
        plt.Line2D([], [], marker="o", ls="", color="grey", label="intact"),
        plt.Line2D([], [], marker="X", ls="", color="grey", markeredgecolor="black",
                   markersize=10, label="lost (predecessor out of view, or a collision)"),
    ]  # fmt: skip
    ax.legend(handles=handles + marks, fontsize=8, loc="center right", bbox_to_anchor=(1.0, 0.45))
    strip.set_yticks(range(len(followers)), followers, fontsize=8)
    strip.set_ylim(-0.7, len(followers) - 0.3)
    strip.set_xticks(sorted(table["leader_speed_mps"].unique()))
    strip.tick_params(axis="x", labelsize=8)
    strip.set_xlabel("leader speed [m/s]  (o intact, X lost)")
    strip.grid(axis="x", alpha=0.3)
    fig.savefig(path, dpi=150)
    plt.close(fig)


def follower_range_max_m() -> float:
    """``range_max`` of the scenario's follower scan (the paper's 1.0 m)."""
    from platoon_sumo.sensors.laser import LaserConfig

    sensor = dict(yaml.safe_load(SCENARIO.read_text())["platoons"][0]["follower"]["sensor"])
    return LaserConfig.preset(sensor.pop("preset"), **sensor).range_max_m


def _share_text(share: float) -> str:
    """A percentage that reads 100 % only when it is 100 %."""
    return f"{share:.1%}" if 0.995 <= share < 1.0 else f"{share:.0%}"


def _arc_cell(row: Any) -> str:
    state = "intact" if row["intact"] else "**lost**"
    gap = row["min_gap_m"]
    text = f"{state} (in view {_share_text(row['min_in_view_share'])}"
    if isinstance(gap, (int, float)) and math.isfinite(gap):  # None (NaN in pandas): no gap
        text += f", min gap {gap:.2f} m"
    n = int(row["collisions"])
    if n:
        events = row.get("collision_events")
        text += f", {n} collision{'s' if n != 1 else ''}"
        text += f": {events}" if isinstance(events, str) and events else ""
    return text + ")"


def write_arc_outputs(rows: list[dict[str, Any]], out: Path, command: str) -> None:
    """Table, CSV, JSON and PNG of the paper follower's ``arc_time_s`` sweep."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    table = pd.DataFrame(rows).sort_values(["arc_time_s", "leader_speed_mps"])
    table.to_csv(out / f"{ARC_STUDY}.csv", index=False)
    arcs = sorted({float(r["arc_time_s"]) for r in rows})
    range_max = follower_range_max_m()
    headers = [f"`arc_time_s` {a:g} s" for a in arcs]
    lines = _speed_grid(table, "arc_time_s", arcs, headers, _arc_cell)
    speeds = {a: intact_speeds(rows, "paper_follower", a) for a in arcs}
    best = {a: highest_intact(rows, "paper_follower", a) for a in arcs}
    contiguous = {a: highest_intact_from_lowest(rows, "paper_follower", a) for a in arcs}
    tested = sorted({float(r["leader_speed_mps"]) for r in rows})
    lines += [
        "",
        "`paper_follower`, everything but `arc_time_s` as in the scenario. Intact: every "
        "follower kept >= 1 ray on its predecessor at every scan after first seeing it, and "
        "0 collisions (robots or walls; none unless listed). In view: the worst follower's "
        "share of such scans. Min gap: the smallest ground-truth bumper gap of any follower to "
        f"its predecessor. `range_max` of the follower scan: {range_max:g} m.",
        "",
        f"Tested leader speeds [m/s]: {_speeds_text(tested)}",
        "",
        "| `arc_time_s` [s] | range_max / arc_time_s [m/s] | intact at [m/s] "
        "| highest intact [m/s] | intact at every speed up to [m/s] |",
        "|---|---|---|---|---|",
    ]
    for a in arcs:
        lines.append(
            f"| {a:g} | {range_max / a:.3g} | {_intact_cells(speeds[a], best[a], contiguous[a])} |"
        )
    lines += ["", f"Command: `{command}`"]
    (out / f"{ARC_STUDY}.md").write_text("\n".join(lines) + "\n")
    summary = {
        "command": command,
        "range_max_m": range_max,
        "intact_speeds": {f"{a:g}": v for a, v in speeds.items()},
        "highest_intact": {f"{a:g}": v for a, v in best.items()},
        "highest_intact_from_lowest": {f"{a:g}": v for a, v in contiguous.items()},
        "rows": rows,
    }
    (out / f"{ARC_STUDY}.json").write_text(json.dumps(summary, indent=2) + "\n")
    _plot_arc(table, arcs, range_max, out / f"{ARC_STUDY}.png", plt)


def _plot_arc(table: Any, arcs: list[float], range_max: float, path: Path, plt: Any) -> None:
    """One row per arc_time_s: o intact / X lost at each leader speed (labelled with the
    worst follower's in-view share), a bar under the row at range_max / arc_time_s."""
    fig, ax = plt.subplots(figsize=(7.5, 1.6 + 0.75 * len(arcs)), layout="constrained")
    speeds = sorted(table["leader_speed_mps"].unique())
    step = min((b - a for a, b in itertools.pairwise(speeds)), default=0.1)
    left, right = speeds[0] - step, speeds[-1] + step
    for i, a in enumerate(arcs):
        part = table[table["arc_time_s"] == a]
        ok, bad = part[part["intact"]], part[~part["intact"]]
        ax.plot(ok["leader_speed_mps"], [i] * len(ok), "o", color="C2", markersize=9)
        ax.plot(bad["leader_speed_mps"], [i] * len(bad), "X", color="C3",
                markeredgecolor="black", markersize=11)  # fmt: skip
        for _, row in part.iterrows():
            label = _share_text(row["min_in_view_share"])
            if row["collisions"]:
                label += f", {int(row['collisions'])} coll."
            ax.annotate(label, (row["leader_speed_mps"], i), xytext=(0, 9),
                        textcoords="offset points", ha="center", fontsize=7)  # fmt: skip
        ceiling = range_max / a
        if ceiling <= right:
            ax.plot([ceiling, ceiling], [i - 0.45, i - 0.12], "-", color="C0", lw=2.5)
            ax.annotate(f"{ceiling:.3g}", (ceiling, i - 0.3), xytext=(4, 0), va="center",
                        textcoords="offset points", fontsize=7, color="C0")  # fmt: skip
        else:
            ax.annotate(f"{ceiling:.3g} \u2192", (right, i - 0.3), ha="right", va="center",
                        fontsize=7, color="C0")  # fmt: skip
    marks = [
        plt.Line2D([], [], marker="o", ls="", color="C2", label="intact"),
        plt.Line2D([], [], marker="X", ls="", color="C3", markeredgecolor="black",
                   markersize=10, label="lost"),
        plt.Line2D([], [], marker="|", ls="", color="C0", markersize=12, markeredgewidth=2.5,
                   label=f"range_max / arc_time_s [m/s] (range_max {range_max:g} m)"),
    ]  # fmt: skip
    fig.legend(handles=marks, fontsize=8, loc="outside lower center", ncol=3, frameon=False)
    ax.set_yticks(range(len(arcs)), [f"{a:g} s" for a in arcs])
    ax.set_ylim(-0.6, len(arcs) - 0.35)
    ax.set_ylabel("arc_time_s")
    ax.set_xlim(left, right)
    ax.set_xticks(speeds)
    ax.tick_params(axis="x", labelsize=8)
    ax.set_xlabel("leader speed [m/s]  (labels: worst follower's scans with predecessor in view)")
    ax.set_title("Paper follower (Algorithm 2), speed = arc / arc_time_s: is the platoon intact?",
                 fontsize=10)  # fmt: skip
    ax.grid(axis="x", alpha=0.3)
    fig.savefig(path, dpi=150)
    plt.close(fig)


def load_rows(out: Path, stem: str = STUDY) -> tuple[list[dict[str, Any]], str | None]:
    """Rows (and the command, if recorded) of a previous study in ``out``."""
    data = json.loads((out / f"{stem}.json").read_text())
    command = data.get("command")
    if command is None and (out / f"{stem}.md").exists():
        for line in (out / f"{stem}.md").read_text().splitlines():
            if line.startswith("Command: `") and line.endswith("`"):
                command = line[len("Command: `") : -1]
    return data["rows"], command


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--speeds", type=float, nargs="+", default=list(DEFAULT_SPEEDS))
    parser.add_argument(
        "--followers", nargs="+", choices=FOLLOWERS, help=f"default: {' '.join(FOLLOWERS)}"
    )
    parser.add_argument(
        "--arc-times",
        type=float,
        nargs="+",
        metavar="S",
        help="instead: the paper follower only, once per arc_time_s [s] and speed "
        "(writes arc_time_study.*)",
    )
    parser.add_argument(
        "--lap-fraction",
        type=float,
        default=1.0,
        help="distance driven per run, in laps (after 20 s of start-up)",
    )
    parser.add_argument("--jobs", type=int, default=2, help="parallel SUMO processes")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "speed_study")
    parser.add_argument(
        "--replot",
        action="store_true",
        help="no runs: rewrite the table, CSV, JSON and PNG of each study found in OUT "
        "(speed_study.json, arc_time_study.json)",
    )
    args = parser.parse_args(argv)  # fmt: skip
    if args.arc_times is not None:
        if args.followers not in (None, ["paper_follower"]):
            parser.error("--arc-times runs paper_follower only")
        if min(args.arc_times) <= 0:
            parser.error("--arc-times: every arc_time_s must be > 0")
    writers = {STUDY: write_outputs, ARC_STUDY: write_arc_outputs}
    if args.replot:
        found = [stem for stem in writers if (args.out / f"{stem}.json").exists()]
        if not found:
            parser.error(f"--replot: no speed_study.json or arc_time_study.json in {args.out}")
        for stem in found:
            rows, command = load_rows(args.out, stem)
            writers[stem](rows, args.out, command or "(command not recorded)")
            print((args.out / f"{stem}.md").read_text())
        return 0
    followers = args.followers or list(FOLLOWERS)
    rows = study(args.speeds, followers, args.lap_fraction, args.jobs, args.arc_times)
    shown = " ".join(sys.argv[1:]) if argv is None else " ".join(argv)
    stem = STUDY if args.arc_times is None else ARC_STUDY
    writers[stem](rows, args.out, f"python tools/speed_study.py {shown}".strip())
    print((args.out / f"{stem}.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
