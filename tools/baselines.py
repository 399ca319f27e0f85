"""The baseline comparison: every follower on every protocol, one table.

Runs each protocol scenario of `scenarios/protocols/` with each follower setting below
swapped into its follower block (the leader and road stay, the vehicles but for
`VEHICLE_OVERRIDES`; a protocol in `SKIPPED` is not run for that controller), SUMO's own
car-following models among them (`SUMO_FOLLOWERS`: the `sumo_driver` controller, SUMO's
model deciding the followers' speed in the project's own runs), and writes the table of
docs/baselines.md between its markers:

    python tools/baselines.py [--work DIR] [--doc]

Per run, over the followers from the disturbance on (`outputs.metrics_start_s`): the
largest spacing error (not for SUMO's models, which declare no spacing policy), the
worst member-to-member acceleration l2 gain, the smallest gap and time to collision to
the vehicle ahead, the RMS jerk, the largest ratio of peak spacing errors from one
follower to the next (l-inf), collisions, the run's string-stability verdict
(platoons.csv) with its worst frequency gain and the share of follower steps in their
main mode (cacc's fall-back shows as a share below 100 %).
Gains and ratios are taken only where the member ahead kept `MIN_INPUT_SHARE` of the
largest norm or peak, as the project's metrics do.
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
PROTOCOLS = ("sinusoid", "braking", "stop_and_go", "cut_in")
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
#: the communication baselines, each on an ideal channel, with delay and with loss:
#: (row label, controller, its params); the main mode is the controller's name
COOPERATIVE = (
    ("cacc, h 0.5 s", "cacc", {"time_gap_s": 0.5}),
    ("path_cacc, 5 m", "path_cacc", {"spacing_m": 5.0}),
)
for _label, _type, _params in COOPERATIVE:
    for _delay, _loss in ((0.0, 0.0), (0.1, 0.0), (0.3, 0.0), (0.0, 0.1), (0.0, 0.3)):
        FOLLOWERS[f"{_label}, delay {_delay * 1000:.0f} ms, loss {_loss:.0%}"] = (
            {"type": _type, "params": _params,
             "sensors": [{"type": "radar"}, _v2v(_delay, _loss)]},
            [_v2v(_delay, _loss)], _type,
        )  # fmt: skip


#: Vehicle keys a controller needs changed from the protocol's, by controller type: with
#: lane actuation SUMO's safe speed caps the command and keeps `min_gap_m + sumo_tau_s v`
#: (5.3 m at 100 km/h with the protocol's 2.5 m), more than path_cacc's constant 5 m; at
#: 1 m it stays SUMO's safety net and leaves the law its spacing.
VEHICLE_OVERRIDES: dict[str, dict[str, Any]] = {"path_cacc": {"min_gap_m": 1.0}}

#: Protocols a controller type is not run on. The cut-in car appears 3 m behind the
#: leader's rear (cut_in.rou.xml), where a platoon at path_cacc's constant 5 m has its
#: first follower: SUMO inserts it on top of that car, a collision of the placement,
#: and no lane-change model merges into a 5 m gap at 100 km/h.
SKIPPED: dict[str, tuple[str, ...]] = {"path_cacc": ("cut_in",)}


#: SUMO's own car-following models as followers (`sumo_driver`: SUMO's model decides the
#: speed, no actuator lag, no sensor: they read SUMO's ground truth; SUMO's CACC gets no
#: communicated acceleration, and behind a leader of another model it runs as ACC):
#: name -> sumo_driver params. Time gaps as the project's controllers'; the standstill
#: gap (minGap) as the laser follower's.
SUMO_FOLLOWERS: dict[str, dict[str, Any]] = {
    "SUMO Krauss, tau 1.2 s": {"car_follow_model": "Krauss", "tau_s": 1.2},
    "SUMO IDM, T 1.2 s": {"car_follow_model": "IDM", "tau_s": 1.2},
    "SUMO ACC, 1.2 s": {"car_follow_model": "ACC", "tau_s": 1.2},
    "SUMO CACC, 0.5 s": {"car_follow_model": "CACC", "tau_s": 0.5},
}
for _name, _params in SUMO_FOLLOWERS.items():
    FOLLOWERS[_name] = (
        {"type": "sumo_driver", "params": {**_params, "min_gap_m": 2.0}}, [],
        f"sumo_{_params['car_follow_model']}",
    )  # fmt: skip


def scenario_for(protocol: str, follower: str, folder: Path) -> Path:
    """The protocol's scenario with `follower` swapped in, written into `folder`."""
    source = REPO / "scenarios" / "protocols" / f"{protocol}.yaml"
    doc = yaml.safe_load(source.read_text())
    block, leader_sensors, _ = FOLLOWERS[follower]
    doc["network"]["net_file"] = str((source.parent / doc["network"]["net_file"]).resolve())
    traffic = doc.get("traffic", {})
    traffic["route_files"] = [str(source.parent / f) for f in traffic.get("route_files", [])]
    (platoon,) = doc["platoons"]
    platoon["follower"] = block
    platoon["vehicle"] = {**platoon["vehicle"], **VEHICLE_OVERRIDES.get(block["type"], {})}
    platoon["leader"]["sensors"] = leader_sensors
    doc["outputs"]["directory"] = str(folder / "out")
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def metrics(steps: pd.DataFrame, start_s: float) -> dict[str, Any]:
    """The comparison's columns from per-step rows (`time_s`, `member_index`, `accel_mps2`,
    `jerk_mps3`, `ahead_id`, `ahead_gap_m`: the nearest vehicle ahead, `spacing_error_m`)
    from `start_s` on."""
    t = steps[steps.time_s >= start_s - 1e-9]
    followers = t[t.member_index > 0]
    norms = t.groupby("member_index").accel_mps2.apply(lambda a: float(np.sqrt((a**2).sum())))
    # as the project's verdict: only where the member ahead kept 5 % of the largest norm
    # (the leader's, or in the cut-in the follower behind the car that cut in)
    floor = max(MIN_INPUT_SHARE * norms.max(), 1e-9)
    gains = [norms[i] / norms[i - 1] for i in range(1, len(norms)) if norms[i - 1] >= floor]
    peaks = followers.groupby("member_index").spacing_error_m.apply(lambda e: e.abs().max())
    peak_floor = MIN_INPUT_SHARE * peaks.max()
    ratios = [peaks.iloc[k] / peaks.iloc[k - 1] for k in range(1, len(peaks))
              if peaks.iloc[k - 1] >= peak_floor and peaks.iloc[k - 1] > 0]  # fmt: skip
    return {
        "peak |spacing error| [m]": float(peaks.max()),
        "worst accel l2 gain": max(gains) if gains else float("nan"),
        "min gap ahead [m]": float(followers.ahead_gap_m.min()),
        "min TTC ahead [s]": _min_ttc(followers),
        "RMS jerk [m/s³]": float(np.sqrt((followers.jerk_mps3.dropna() ** 2).mean())),
        "spacing error peak ratio": max(ratios) if ratios else float("nan"),
    }


def _min_ttc(rows: pd.DataFrame) -> float:
    """Smallest gap / closing speed to the vehicle ahead (the same one on both steps)."""
    rows = rows.sort_values(["member_index", "time_s"])
    same = (rows.member_index == rows.member_index.shift()) & (
        rows.ahead_id == rows.ahead_id.shift()
    )
    closing = -(rows.ahead_gap_m.diff()) / rows.time_s.diff()
    ttc = rows.ahead_gap_m / closing
    ttc = ttc[same & (closing > 1e-6)]
    return float(ttc.min()) if len(ttc) else float("nan")


def project_run(out: Path, start_s: float, main_mode: str) -> dict[str, Any]:
    """A platoon-sumo run's row: `metrics` of its trajectories, its collisions, and its
    own verdict and controller modes."""
    t = pd.read_csv(out / "trajectories.csv")
    summary = pd.read_json(out / "summary.json", typ="series")
    followers = t[(t.time_s >= start_s - 1e-9) & (t.member_index > 0)]
    return {
        **metrics(t, start_s),
        "collisions": int(summary["collisions"]) + int(summary["sumo_collisions_with_platoons"]),
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
    runs = [
        (protocol, follower)
        for protocol in PROTOCOLS
        for follower, (block, _, _) in FOLLOWERS.items()
        if protocol not in SKIPPED.get(block["type"], ())
    ]
    total = len(runs)
    for protocol in PROTOCOLS:
        for follower, (_, _, mode) in FOLLOWERS.items():
            if (protocol, follower) not in runs:
                continue
            folder = work / protocol / _folder_name(follower)
            folder.mkdir(parents=True, exist_ok=True)
            plan = load_plan(scenario_for(protocol, follower, folder))
            began = time.process_time()
            run(plan, force=True)
            row = {"protocol": protocol, "follower": follower}
            row |= project_run(folder / "out", plan.scenario.outputs.metrics_start_s, mode)
            rows.append(row)
            _progress(len(rows), total, protocol, follower, began)
    return pd.DataFrame(rows)


#: The followers the figures show, one panel each.
FIGURE_FOLLOWERS = (
    "laser_follower, noisy lidar (3 cm, 1 % dropouts)", "acc, h 1.2 s", "acc, h 0.5 s",
    "cacc, h 0.5 s, delay 0 ms, loss 0%", "cacc, h 0.5 s, delay 300 ms, loss 0%",
    "SUMO ACC, 1.2 s",
)  # fmt: skip
FIGURES = REPO / "docs" / "baselines"


def figures(work: Path, out: Path) -> list[Path]:
    """One PNG per protocol: every member's speed over time for `FIGURE_FOLLOWERS`, one
    panel each (the leader black, the followers from dark to light down the platoon)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    written = []
    for protocol in PROTOCOLS:
        doc = yaml.safe_load((REPO / "scenarios" / "protocols" / f"{protocol}.yaml").read_text())
        start = float(doc["outputs"]["metrics_start_s"])
        fig, axes = plt.subplots(2, 3, figsize=(13, 6.5), sharex=True, sharey=True)
        for ax, follower in zip(axes.flat, FIGURE_FOLLOWERS, strict=True):
            folder = work / protocol / _folder_name(follower)
            rows = pd.read_csv(folder / "out" / "trajectories.csv")
            rows = rows[rows.time_s >= start - 10.0]
            members = sorted(rows.member_index.unique())
            colours = plt.cm.viridis(np.linspace(0.0, 0.85, max(len(members) - 1, 1)))
            for k, (index, series) in enumerate(rows.groupby("member_index")):
                colour = "black" if index == 0 else colours[k - 1]
                ax.plot(
                    series.time_s, series.speed_mps, color=colour, lw=1.4 if index == 0 else 1.0
                )
            ax.axvline(start, color="grey", ls=":", lw=0.8)
            ax.set_title(follower, fontsize=9)
            ax.grid(alpha=0.3)
        for ax in axes[-1]:
            ax.set_xlabel("time [s]")
        for ax in axes[:, 0]:
            ax.set_ylabel("speed [m/s]")
        fig.suptitle(
            f"{protocol}: every member's speed (leader black, followers dark to light down "
            "the platoon; dotted: metrics start)"
        )
        fig.tight_layout()
        path = out / f"{protocol}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        written.append(path)
    return written


def _folder_name(follower: str) -> str:
    return follower.replace(" ", "_").replace(",", "").replace("%", "pc")


def _progress(done: int, total: int, protocol: str, follower: str, began: float) -> None:
    print(
        f"[{done}/{total}] {protocol:12s} {follower:50s} {time.process_time() - began:5.1f} s CPU",
        file=sys.stderr,
    )


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
    parser.add_argument(
        "--doc",
        action="store_true",
        help=f"rewrite the table in {DOC} and its figures in {FIGURES}",
    )
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
        pictures = "\n".join(f"![{p.stem}](baselines/{p.name})" for p in figures(work, FIGURES))
        block = f"Command: `python tools/baselines.py --doc`\n\n{text}\n\n{pictures}\n"
        DOC.write_text(f"{head}{BEGIN}\n{block}{END}{tail}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
