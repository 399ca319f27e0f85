"""The baseline comparison: every follower on every protocol, one table.

Runs each protocol scenario of `scenarios/protocols/` with each follower setting below
swapped into its follower block (the leader and road stay, the vehicles but for
`VEHICLE_OVERRIDES`; a protocol in `SKIPPED` is not run for that controller), then the same
protocol with SUMO's own car-following models driving the followers (`SUMO_FOLLOWERS`,
in libsumo directly: the leader's speed set from the same profile each step), and
writes the table of docs/baselines.md between its markers:

    python tools/baselines.py [--work DIR] [--doc]

Per run, over the followers from the disturbance on (`outputs.metrics_start_s`): the
largest spacing error (not for SUMO's models, which declare no spacing policy), the
worst member-to-member acceleration l2 gain, the smallest gap and time to collision to
the vehicle ahead, the RMS jerk, the largest ratio of peak spacing errors from one
follower to the next (l-inf), collisions, and for the project's controllers their
string-stability verdict (platoons.csv) with its worst frequency gain and the share of
follower steps in their main mode (cacc's fall-back shows as a share below 100 %).
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


#: SUMO's own car-following models as followers, driven by SUMO (no actuator lag, no
#: sensor: they read SUMO's ground truth; SUMO's CACC gets no communicated acceleration):
#: name -> vType attributes. Time gaps as the project's controllers'.
SUMO_FOLLOWERS: dict[str, dict[str, str]] = {
    "SUMO Krauss, tau 1.2 s": {"carFollowModel": "Krauss", "tau": "1.2", "sigma": "0"},
    "SUMO IDM, T 1.2 s": {"carFollowModel": "IDM", "tau": "1.2"},
    "SUMO ACC, 1.2 s": {"carFollowModel": "ACC", "tau": "1.2"},
    "SUMO CACC, 0.5 s": {"carFollowModel": "CACC", "tau": "0.5"},
}


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


def sumo_followers_run(protocol: str, attrs: dict[str, str], folder: Path) -> dict[str, Any]:
    """The protocol with SUMO driving the followers (`attrs`: their vType) behind a
    leader whose speed is set each step from the protocol's profile, in libsumo
    directly. No spacing errors: the models declare no spacing policy."""
    import libsumo

    from platoon_sumo.control.speed_profile import SpeedProfileParams, profile_speed
    from platoon_sumo.sumo.backend import sumo_binary

    source = REPO / "scenarios" / "protocols" / f"{protocol}.yaml"
    doc = yaml.safe_load(source.read_text())
    (platoon,) = doc["platoons"]
    sim, vehicle = doc["simulation"], platoon["vehicle"]
    profile = SpeedProfileParams(**platoon["leader"]["params"])
    length, min_gap = 4.5, 2.0
    common = (
        f'vClass="passenger" length="{length}" width="1.8" minGap="{min_gap}" '
        f'accel="{vehicle["max_accel_mps2"]}" decel="{vehicle["max_decel_mps2"]}" '
        f'emergencyDecel="{vehicle["max_decel_mps2"]}" maxSpeed="{vehicle["max_speed_mps"]}" '
        'speedFactor="1" speedDev="0"'
    )
    follower_attrs = " ".join(f'{k}="{v}"' for k, v in attrs.items())
    slot_m = length + platoon["spacing_m"]
    vehicles = [
        f'<vehicle id="m{i}" type="{"leader" if i == 0 else "follower"}" route="r" depart="0" '
        f'departLane="0" departPos="{platoon["depart_pos_m"] - i * slot_m}"/>'
        for i in range(platoon["members"])
    ]
    routes = folder / "sumo_followers.rou.xml"
    routes.write_text(
        "<routes>\n"
        f'  <vType id="leader" {common} carFollowModel="Krauss" sigma="0" tau="1.0"/>\n'
        f'  <vType id="follower" {common} {follower_attrs}/>\n'
        f'  <route id="r" edges="{" ".join(platoon["route"]["edges"])}"/>\n'
        + "\n".join(f"  {v}" for v in vehicles)
        + "\n</routes>\n"
    )
    net = (source.parent / doc["network"]["net_file"]).resolve()
    cut_in = _cut_in(source, doc)
    if cut_in is not None:
        routes.write_text(routes.read_text().replace("</routes>", cut_in[1] + "\n</routes>"))
    extra: list[str] = []
    libsumo.start([
        sumo_binary(), "-n", str(net), "-r", ",".join([str(routes), *extra]),
        "--step-length", str(sim["step_s"]), "--no-step-log", "true", "--no-warnings", "true",
        "--collision.action", "warn", "--collision.check-junctions", "true", "--seed", "1",
    ])  # fmt: skip
    rows, collisions = [], 0
    ids = [f"m{i}" for i in range(platoon["members"])]
    try:
        t0 = None
        while libsumo.simulation.getTime() < sim["end_s"] - 1e-9:
            now = libsumo.simulation.getTime()
            present = set(libsumo.vehicle.getIDList())
            for vid in libsumo.simulation.getDepartedIDList():
                if vid in ids:  # a platoon keeps its lane: no lane change of SUMO's own
                    libsumo.vehicle.setLaneChangeMode(vid, 0)
            if "m0" in present:
                t0 = now if t0 is None else t0
                libsumo.vehicle.setSpeed("m0", profile_speed(profile, now - t0))
            if cut_in is not None:
                _cut_in_step(now, cut_in[0], length)
            libsumo.simulationStep()
            collisions += libsumo.simulation.getCollidingVehiclesNumber()
            time_s = libsumo.simulation.getTime()
            for index, vid in enumerate(ids):
                if vid not in present:
                    continue
                ahead = libsumo.vehicle.getLeader(vid, 300.0)
                rows.append({
                    "time_s": time_s, "member_index": index,
                    "accel_mps2": libsumo.vehicle.getAcceleration(vid),
                    "speed_mps": libsumo.vehicle.getSpeed(vid),
                    "ahead_id": ahead[0] if ahead and ahead[0] else None,
                    "ahead_gap_m": ahead[1] + min_gap if ahead and ahead[0] else np.nan,
                })  # fmt: skip
    finally:
        libsumo.close()
    steps = pd.DataFrame(rows)
    steps["jerk_mps3"] = steps.groupby("member_index").accel_mps2.diff() / sim["step_s"]
    start = float(doc["outputs"]["metrics_start_s"])
    # SUMO's models declare no spacing policy (IDM's equilibrium gap is not s0 + v T at
    # these speeds): no spacing error
    steps["spacing_error_m"] = np.nan
    steps.to_csv(folder / "steps.csv", index=False)
    return {**metrics(steps, start), "collisions": collisions}


#: Where the cut-in protocol's car appears: this far behind the leader's rear
#: (scenarios/protocols/cut_in.rou.xml places it for the project's leader, which is at a
#: known position then; SUMO's own leader launches faster, so the tool places it).
CUT_IN_BEHIND_LEADER_M = 3.0


def _cut_in(source: Path, doc: dict[str, Any]) -> tuple[float, str] | None:
    """(time, vType XML) of the protocol's cut-in car, if it has one."""
    import xml.etree.ElementTree as ET

    for name in doc.get("traffic", {}).get("route_files", []):
        root = ET.parse(source.parent / name).getroot()
        vehicle, vtype = root.find("vehicle"), root.find("vType")
        if vehicle is not None and vtype is not None:
            return float(vehicle.get("depart", "0")), ET.tostring(vtype, encoding="unicode")
    return None


def _cut_in_step(now: float, depart_s: float, length_m: float) -> None:
    """One second before the cut-in the car drives beside the platoon in the left lane;
    at the cut-in it is moved into the platoon's lane behind the leader."""
    import libsumo

    leader = libsumo.vehicle.getLanePosition("m0")
    if abs(now - (depart_s - 1.0)) < 1e-6:
        libsumo.vehicle.add(
            "cutter", "r", typeID="cutter", departLane="1", departPos=str(leader - 30.0),
            departSpeed=str(libsumo.vehicle.getSpeed("m0")),
        )  # fmt: skip
        libsumo.vehicle.setLaneChangeMode("cutter", 0)
    elif abs(now - depart_s) < 1e-6:
        lane = libsumo.vehicle.getLaneID("m0")
        libsumo.vehicle.moveTo("cutter", lane, leader - length_m - CUT_IN_BEHIND_LEADER_M)
        libsumo.vehicle.setLaneChangeMode("cutter", 1621)  # SUMO's default from now on


def run_all(work: Path) -> pd.DataFrame:
    from platoon_sumo.runner import load_plan, run

    rows = []
    runs = [
        (protocol, follower)
        for protocol in PROTOCOLS
        for follower, (block, _, _) in FOLLOWERS.items()
        if protocol not in SKIPPED.get(block["type"], ())
    ]
    total = len(runs) + len(PROTOCOLS) * len(SUMO_FOLLOWERS)
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
        for follower, attrs in SUMO_FOLLOWERS.items():
            folder = work / protocol / _folder_name(follower)
            folder.mkdir(parents=True, exist_ok=True)
            began = time.process_time()
            row = {"protocol": protocol, "follower": follower}
            row |= sumo_followers_run(protocol, attrs, folder)
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
            source = folder / "out" / "trajectories.csv"
            rows = pd.read_csv(source if source.exists() else folder / "steps.csv")
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
