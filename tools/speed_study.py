"""Speed study of the paper's experiment: up to which leader speed does the platoon hold?

Runs `scenarios/paper_world.yaml` at increasing leader speeds, once with the paper's
follower (Algorithm 2) and once with platoon-sumo's `laser_follower`, both on the
paper's follower scan, and reports for each run whether the platoon stayed intact:
every follower kept its predecessor in its scan at every scan after first seeing it,
and no collision happened (with anything: another robot or a wall). Writes a Markdown
table, a CSV, a JSON and a PNG. The summary lists, per follower, every tested speed at
which the platoon stayed intact and the highest of them; intact speeds need not be
contiguous (see docs/paper.md, "Speed study", for a failure at the lowest speed only).

    python tools/speed_study.py                    # full study (a few minutes on 2 cores)
    python tools/speed_study.py --speeds 0.1 0.3 --lap-fraction 0.25 --out /tmp/study
    python tools/speed_study.py --replot           # redo table/PNG from OUT/speed_study.json
"""

from __future__ import annotations

import argparse
import json
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


def scenario_for(case: Case, base: dict[str, Any]) -> dict[str, Any]:
    """The paper scenario with the leader's speed and the follower under test."""
    data = yaml.safe_load(yaml.safe_dump(base))  # deep copy
    platoon = data["platoons"][0]
    leader = platoon["leader"]
    leader.setdefault("params", {})["linear_mps"] = case.speed_mps
    chosen = FOLLOWERS[case.follower]
    if chosen is not None:
        platoon["follower"] = {**chosen, "sensor": platoon["follower"]["sensor"]}
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
    return {
        "follower": case.follower,
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


def study(
    speeds: Sequence[float], followers: Sequence[str], lap_fraction: float, jobs: int
) -> list[dict[str, Any]]:
    base = yaml.safe_load(SCENARIO.read_text())
    cases = [
        Case(f, v, end_s=round(20.0 + lap_fraction * LAP_M / v, 2))
        for f in followers
        for v in speeds
    ]
    context = multiprocessing.get_context("spawn")
    with context.Pool(processes=jobs, maxtasksperchild=1) as pool:
        pending = [pool.apply_async(run_case, (c, base)) for c in cases]
        rows = []
        for c, p in zip(cases, pending, strict=True):
            row = p.get()
            rows.append(row)
            mark = "intact" if row["intact"] else "broken"
            print(f"{c.follower:15s} {c.speed_mps:5.2f} m/s: {mark}", file=sys.stderr)
    return rows


def intact_speeds(rows: list[dict[str, Any]], follower: str) -> list[float]:
    """Every tested leader speed at which the platoon with this follower stayed intact."""
    return sorted(
        float(r["leader_speed_mps"]) for r in rows if r["follower"] == follower and r["intact"]
    )


def highest_intact(rows: list[dict[str, Any]], follower: str) -> float | None:
    """Highest tested speed at which the platoon stayed intact (None: at none)."""
    speeds = intact_speeds(rows, follower)
    return speeds[-1] if speeds else None


def highest_intact_from_lowest(rows: list[dict[str, Any]], follower: str) -> float | None:
    """Highest speed such that every tested speed up to it kept the platoon intact
    (the study's former headline; None when the lowest tested speed already failed)."""
    best = None
    for row in sorted((r for r in rows if r["follower"] == follower),
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


def write_outputs(rows: list[dict[str, Any]], out: Path, command: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    table = pd.DataFrame(rows).sort_values(["follower", "leader_speed_mps"])
    table.to_csv(out / "speed_study.csv", index=False)
    followers = list(dict.fromkeys(r["follower"] for r in rows))
    lines = [
        "| leader speed [m/s] | " + " | ".join(f"`{f}`" for f in followers) + " |",
        "|---|" + "---|" * len(followers),
    ]
    for speed, group in table.groupby("leader_speed_mps"):
        cells = []
        for f in followers:
            r = group[group["follower"] == f]
            cells.append("" if r.empty else _cell(r.iloc[0]))
        lines.append(f"| {speed:g} | " + " | ".join(cells) + " |")
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
        b, c = best[f], contiguous[f]
        lines.append(
            f"| `{f}` | {_speeds_text(speeds[f])} | {'none' if b is None else f'{b:g}'} "
            f"| {'none (lowest speed lost)' if c is None else f'{c:g}'} |"
        )
    lines += ["", f"Command: `{command}`"]
    (out / "speed_study.md").write_text("\n".join(lines) + "\n")
    summary = {
        "command": command,
        "intact_speeds": speeds,
        "highest_intact": best,
        "highest_intact_from_lowest": contiguous,
        "rows": rows,
    }
    (out / "speed_study.json").write_text(json.dumps(summary, indent=2) + "\n")
    _plot(table, followers, out / "speed_study.png", plt)


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


def load_rows(out: Path) -> tuple[list[dict[str, Any]], str | None]:
    """Rows (and the command, if recorded) of a previous study in ``out``."""
    data = json.loads((out / "speed_study.json").read_text())
    command = data.get("command")
    if command is None and (out / "speed_study.md").exists():
        for line in (out / "speed_study.md").read_text().splitlines():
            if line.startswith("Command: `") and line.endswith("`"):
                command = line[len("Command: `") : -1]
    return data["rows"], command


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--speeds", type=float, nargs="+", default=list(DEFAULT_SPEEDS))
    parser.add_argument("--followers", nargs="+", default=list(FOLLOWERS), choices=FOLLOWERS)
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
        help="no runs: rewrite the table, CSV, JSON and PNG from OUT/speed_study.json",
    )
    args = parser.parse_args(argv)  # fmt: skip
    if args.replot:
        rows, command = load_rows(args.out)
        write_outputs(rows, args.out, command or "(command not recorded)")
        print((args.out / "speed_study.md").read_text())
        return 0
    rows = study(args.speeds, args.followers, args.lap_fraction, args.jobs)
    shown = " ".join(sys.argv[1:]) if argv is None else " ".join(argv)
    write_outputs(rows, args.out, f"python tools/speed_study.py {shown}".strip())
    print((args.out / "speed_study.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
