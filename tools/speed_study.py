"""Speed study of the paper's experiment: up to which leader speed does the platoon hold?

Runs `scenarios/paper_world.yaml` at increasing leader speeds, once with the paper's
follower (Algorithm 2) and once with platoon-sumo's `laser_follower`, both on the
paper's follower scan, and reports for each run whether the platoon stayed intact:
every follower kept its predecessor in its scan at every scan after first seeing it,
and no collision happened. Writes a Markdown table, a CSV and a PNG.

    python tools/speed_study.py                    # full study (a few minutes on 2 cores)
    python tools/speed_study.py --speeds 0.1 0.3 --lap-fraction 0.25 --out /tmp/study
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
    return {
        "follower": case.follower,
        "leader_speed_mps": case.speed_mps,
        "simulated_s": summary["simulated_s"],
        "intact": intact,
        "min_in_view_share": min(shares) if shares else 0.0,
        "lost_scans": lost,
        "collisions": summary["collisions"],
        "min_gap_m": min_gap,
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


def highest_intact(rows: list[dict[str, Any]], follower: str) -> float | None:
    """Highest speed below which every tested speed kept the platoon intact."""
    best = None
    for row in sorted((r for r in rows if r["follower"] == follower),
                      key=lambda r: r["leader_speed_mps"]):  # fmt: skip
        if not row["intact"]:
            break
        best = row["leader_speed_mps"]
    return best


def write_outputs(rows: list[dict[str, Any]], out: Path, command: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    table = pd.DataFrame(rows).sort_values(["follower", "leader_speed_mps"])
    table.to_csv(out / "speed_study.csv", index=False)
    followers = list(dict.fromkeys(table["follower"]))
    lines = [
        "| leader speed [m/s] | " + " | ".join(f"`{f}`" for f in followers) + " |",
        "|---|" + "---|" * len(followers),
    ]
    for speed, group in table.groupby("leader_speed_mps"):
        cells = []
        for f in followers:
            r = group[group["follower"] == f]
            if r.empty:
                cells.append("")
                continue
            row = r.iloc[0]
            state = "intact" if row["intact"] else "**lost**"
            cells.append(
                f"{state} (in view {row['min_in_view_share']:.0%}, "
                f"{int(row['collisions'])} collisions)"
            )
        lines.append(f"| {speed:g} | " + " | ".join(cells) + " |")
    best = {f: highest_intact(rows, f) for f in followers}
    lines += ["", "Highest leader speed with the platoon intact at every lower tested speed:"]
    lines += [f"- `{f}`: {v if v is not None else 'none'} m/s" for f, v in best.items()]
    lines += ["", f"Command: `{command}`"]
    (out / "speed_study.md").write_text("\n".join(lines) + "\n")
    (out / "speed_study.json").write_text(json.dumps({"best": best, "rows": rows}, indent=2))

    fig, ax = plt.subplots(figsize=(7, 3.8), layout="constrained")
    for i, f in enumerate(followers):
        part = table[table["follower"] == f]
        ax.plot(part["leader_speed_mps"], part["min_in_view_share"] * 100, "o-", label=f,
                color=f"C{i}")  # fmt: skip
        broken = part[~part["intact"]]
        ax.plot(broken["leader_speed_mps"], broken["min_in_view_share"] * 100, "x",
                color=f"C{i}", markersize=10)  # fmt: skip
    ax.set_xlabel("leader speed [m/s]")
    ax.set_ylabel("worst follower: scans with predecessor in view [%]")
    ax.set_title("Paper world, 5 robots: does every follower keep its predecessor? (x = lost)")
    ax.set_ylim(-5, 105)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.savefig(out / "speed_study.png", dpi=150)
    plt.close(fig)


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
    args = parser.parse_args(argv)  # fmt: skip
    rows = study(args.speeds, args.followers, args.lap_fraction, args.jobs)
    shown = " ".join(sys.argv[1:]) if argv is None else " ".join(argv)
    write_outputs(rows, args.out, f"python tools/speed_study.py {shown}".strip())
    print((args.out / "speed_study.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
