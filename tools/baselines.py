"""The baseline comparison: every follower on every protocol, one table.

Runs each protocol scenario of `scenarios/protocols/` with each follower setting below
swapped into its follower block (the leader, vehicles and road stay), and writes the
table of docs/baselines.md between its markers:

    python tools/baselines.py [--work DIR] [--doc]

Per run, over the followers from the disturbance on (`outputs.metrics_start_s`): the
largest peak spacing error of a member, the worst member-to-member acceleration l2 gain
(computed here from trajectories.csv), the smallest gap and time to collision, the RMS
jerk, collisions, and the share of follower steps each controller spent in its main
mode (cacc's fall-back shows as a share below 100 %), and the project's own
string-stability verdict (platoons.csv) with its worst frequency gain. Gains are taken
only where the member ahead kept `MIN_INPUT_SHARE` of the leader's acceleration norm.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from platoon_sumo.metrics.string_stability import MIN_INPUT_SHARE

REPO = Path(__file__).resolve().parent.parent
PROTOCOLS = ("sinusoid", "braking", "stop_and_go")
DOC = REPO / "docs" / "baselines.md"
BEGIN, END = "<!-- baselines -->", "<!-- /baselines -->"

LIDAR = {"preset": "lidar_120m"}
NOISY_LIDAR = {"preset": "lidar_120m", "overrides": {"noise_std_m": 0.03, "dropout_prob": 0.01}}


def _v2v(delay_s: float = 0.0, loss: float = 0.0) -> dict[str, Any]:
    return {"type": "v2v", "params": {"delay_s": delay_s, "loss_probability": loss}}


#: name -> (follower block, the leader's extra sensors, the follower's main mode)
FOLLOWERS: dict[str, tuple[dict[str, Any], list[dict[str, Any]], str]] = {
    "laser_follower": (
        {"type": "laser_follower", "params": {"time_gap_s": 1.2, "standstill_gap_m": 2.0},
         "sensor": LIDAR}, [], "following",
    ),
    "laser_follower, noisy lidar (3 cm, 1 % dropouts)": (
        {"type": "laser_follower", "params": {"time_gap_s": 1.2, "standstill_gap_m": 2.0},
         "sensor": NOISY_LIDAR}, [], "following",
    ),
    "acc, h 1.2 s": (
        {"type": "acc", "params": {"time_gap_s": 1.2}, "sensors": [{"type": "radar"}]}, [], "acc",
    ),
    "acc, h 0.5 s": (
        {"type": "acc", "params": {"time_gap_s": 0.5}, "sensors": [{"type": "radar"}]}, [], "acc",
    ),
}  # fmt: skip
for _delay, _loss in ((0.0, 0.0), (0.1, 0.0), (0.3, 0.0), (0.0, 0.1), (0.0, 0.3)):
    FOLLOWERS[f"cacc, h 0.5 s, delay {_delay * 1000:.0f} ms, loss {_loss:.0%}"] = (
        {"type": "cacc", "params": {"time_gap_s": 0.5},
         "sensors": [{"type": "radar"}, _v2v(_delay, _loss)]},
        [_v2v(_delay, _loss)], "cacc",
    )  # fmt: skip


def scenario_for(protocol: str, follower: str, folder: Path) -> Path:
    """The protocol's scenario with `follower` swapped in, written into `folder`."""
    source = REPO / "scenarios" / "protocols" / f"{protocol}.yaml"
    doc = yaml.safe_load(source.read_text())
    block, leader_sensors, _ = FOLLOWERS[follower]
    doc["network"]["net_file"] = str((source.parent / doc["network"]["net_file"]).resolve())
    (platoon,) = doc["platoons"]
    platoon["follower"] = block
    platoon["leader"]["sensors"] = leader_sensors
    doc["outputs"]["directory"] = str(folder / "out")
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def metrics(out: Path, start_s: float, main_mode: str) -> dict[str, Any]:
    t = pd.read_csv(out / "trajectories.csv")
    t = t[t.time_s >= start_s]
    followers = t[t.member_index > 0]
    norms = t.groupby("member_index").accel_mps2.apply(lambda a: float(np.sqrt((a**2).sum())))
    # as the project's verdict: only where the member ahead kept 5 % of the leader's norm
    floor = MIN_INPUT_SHARE * norms.iloc[0]
    gains = [norms[i] / norms[i - 1] for i in range(1, len(norms)) if norms[i - 1] >= floor]
    peaks = followers.groupby("member_index").spacing_error_m.apply(lambda e: e.abs().max())
    summary = pd.read_json(out / "summary.json", typ="series")
    return {
        "peak |spacing error| [m]": float(peaks.max()),
        "worst accel l2 gain": max(gains) if gains else float("nan"),
        "min gap [m]": float(followers.gap_to_predecessor_m.min()),
        "min TTC [s]": float(followers.ttc_s.min()) if followers.ttc_s.notna().any() else None,
        "RMS jerk [m/s³]": float(np.sqrt((followers.jerk_mps3.dropna() ** 2).mean())),
        "collisions": int(summary["collisions"]),
        "spacing error peak ratio": _platoon(out)["max_spacing_error_peak_ratio"],
        "verdict (worst frequency gain)": _verdict(out),
        "main mode share": float((followers.controller_mode == main_mode).mean()),
    }


def _platoon(out: Path) -> dict[str, Any]:
    """The run's one row of platoons.csv."""
    (row,) = pd.read_csv(out / "platoons.csv").to_dict("records")
    return row


def _verdict(out: Path) -> str:
    """The project's string-stability verdict (platoons.csv) with its worst gain."""
    row = _platoon(out)
    gain = row["max_frequency_gain"]
    return row["string_stability_verdict"] + ("" if pd.isna(gain) else f" ({gain:.2f})")


def run_all(work: Path) -> pd.DataFrame:
    from platoon_sumo.runner import load_plan, run

    rows = []
    total = len(PROTOCOLS) * len(FOLLOWERS)
    for protocol in PROTOCOLS:
        for follower, (_, _, mode) in FOLLOWERS.items():
            folder = (
                work / protocol / follower.replace(" ", "_").replace(",", "").replace("%", "pc")
            )
            folder.mkdir(parents=True, exist_ok=True)
            plan = load_plan(scenario_for(protocol, follower, folder))
            began = time.process_time()
            run(plan, force=True)
            row = {"protocol": protocol, "follower": follower}
            row |= metrics(folder / "out", plan.scenario.outputs.metrics_start_s, mode)
            rows.append(row)
            print(
                f"[{len(rows)}/{total}] {protocol:12s} {follower:50s} "
                f"{time.process_time() - began:5.1f} s CPU",
                file=sys.stderr,
            )
    return pd.DataFrame(rows)


def _cell(column: str, value: Any) -> str:
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return "—"
    if column == "main mode share":
        return f"{value:.0%}"
    return f"{value:.2f}" if isinstance(value, float) else str(value)


def markdown(table: pd.DataFrame) -> str:
    columns = list(table.columns)
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in table.itertuples(index=False):
        lines.append(
            "| " + " | ".join(_cell(c, v) for c, v in zip(columns, row, strict=True)) + " |"
        )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, help="folder for the runs (default: a temp dir)")
    parser.add_argument("--doc", action="store_true", help=f"rewrite the table in {DOC}")
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="baselines_"))
    table = run_all(work)
    table.to_csv(work / "baselines.csv", index=False)
    text = markdown(table)
    print(text)
    if args.doc:
        doc = DOC.read_text()
        head, rest = doc.split(BEGIN)
        _, tail = rest.split(END)
        block = f"Command: `python tools/baselines.py --doc`\n\n{text}\n"
        DOC.write_text(f"{head}{BEGIN}\n{block}{END}{tail}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
