"""PNG figures of one run (and overlays of several), drawn from a results folder's tables.

matplotlib is imported inside each function with the Agg backend, so importing this
module never touches a display or picks a backend for the caller.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

DPI = 120


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _colors(n: int) -> list[Any]:
    plt = _plt()
    cmap = plt.get_cmap("viridis")
    return [cmap(x) for x in np.linspace(0.0, 0.85, max(n, 1))]


def _members(traj: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """(vehicle id, its rows in time order), ordered by member index."""
    order = traj.groupby("vehicle_id")["member_index"].first().sort_values()
    return [(str(v), traj[traj["vehicle_id"] == v].sort_values("time_s")) for v in order.index]


def _label(vid: str, rows: pd.DataFrame) -> str:
    role = rows["role"].iloc[0]
    return f"{vid} ({role})" if role == "leader" else vid


def _save(fig: Any, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    _plt().close(fig)
    return path


def platoon_colors(traj: pd.DataFrame) -> dict[str, dict[str, Any]]:
    """{platoon id: {vehicle id: colour}}: one hue per platoon (tab10, in platoon-id
    order) so platoons can be told apart, its members in shades of it from the leader
    (the full colour) to the last follower (the palest), so order shows too."""
    plt = _plt()
    from matplotlib.colors import to_rgb

    colors: dict[str, dict[str, Any]] = {}
    for k, pid in enumerate(sorted(traj["platoon_id"].astype(str).unique())):
        base = np.array(to_rgb(plt.get_cmap("tab10")(k % 10)))
        members = _members(traj[traj["platoon_id"].astype(str) == pid])
        paleness = np.linspace(0.0, 0.6, len(members)) if len(members) > 1 else [0.0]
        colors[pid] = {
            vid: tuple(base + (1.0 - base) * p)
            for (vid, _), p in zip(members, paleness, strict=True)
        }
    return colors


def draw_network(ax: Any, net_file: Path | None) -> Any:
    """The network's lanes (lines) and junctions (filled) on `ax`, below everything else;
    returns the lanes' LineCollection (None, and nothing drawn, without the net file)."""
    if net_file is None or not net_file.is_file():
        return None
    import sumolib
    from matplotlib.collections import LineCollection

    net = sumolib.net.readNet(str(net_file), withInternal=True)
    shapes = [lane.getShape() for edge in net.getEdges() for lane in edge.getLanes()]
    lanes = ax.add_collection(LineCollection(shapes, colors="0.8", linewidths=1.0, zorder=1))
    junctions = [n.getShape() for n in net.getNodes() if len(n.getShape()) >= 3]
    for shape in junctions:
        ax.fill(*zip(*shape, strict=True), color="0.93", zorder=0)
    return lanes


def network_map(traj: pd.DataFrame, net_file: Path | None, path: Path) -> Path:
    """Every platoon vehicle's path over the lanes of the network (sumolib shapes)."""
    fig = network_map_figure(traj, net_file)
    fig.savefig(path, dpi=DPI, bbox_inches="tight")
    _plt().close(fig)
    return path


def network_map_figure(traj: pd.DataFrame, net_file: Path | None) -> Any:
    """The map of `network_map`: one colour per platoon (`platoon_colors`), the leader's
    path drawn thicker, a legend entry per platoon."""
    plt = _plt()
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(8.0, 7.0), layout="constrained")
    x0, x1 = traj["x_m"].min(), traj["x_m"].max()
    y0, y1 = traj["y_m"].min(), traj["y_m"].max()
    pad = max(30.0, 0.08 * max(x1 - x0, y1 - y0))
    draw_network(ax, net_file)
    handles = []
    for pid, colors in platoon_colors(traj).items():
        members = _members(traj[traj["platoon_id"].astype(str) == pid])
        for vid, rows in members:
            color = colors[vid]
            lead = rows["role"].iloc[0] == "leader"  # below, so followers show along it
            ax.plot(rows["x_m"], rows["y_m"], color=color, lw=2.8 if lead else 1.0,
                    zorder=3 if lead else 4)  # fmt: skip
            ax.plot(rows["x_m"].iloc[0], rows["y_m"].iloc[0], "o", color=color, ms=4, zorder=5)
            ax.plot(rows["x_m"].iloc[-1], rows["y_m"].iloc[-1], "s", color=color, ms=4, zorder=5)
        leader = members[0][0]
        handles.append(Line2D([], [], color=colors[leader], lw=2.8, label=(
            f"platoon {pid}: {len(members)} vehicle{'s' if len(members) > 1 else ''}, "
            f"leader {leader} (thick)")))  # fmt: skip
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Platoon paths over the network (front bumpers; o start, \u25a0 end;\n"
                 "one colour per platoon, followers paler along it)")  # fmt: skip
    if len(handles) <= 6:
        ax.legend(handles=handles, loc="best", fontsize=8)
    else:  # below the map, where it hides no path
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), fontsize=8,
                  ncol=min(3, 1 + len(handles) // 6))  # fmt: skip
    ax.grid(True, alpha=0.3)
    return fig


def spacing_and_speed(traj: pd.DataFrame, platoon_id: str, path: Path) -> Path:
    """Speed of every member and spacing error of every follower over time."""
    return _save(spacing_and_speed_figure(traj, platoon_id), path)


def spacing_and_speed_figure(traj: pd.DataFrame, platoon_id: str) -> Any:
    """The figure of `spacing_and_speed`; the lower panel says n/a without a follower."""
    plt = _plt()
    members = _members(traj[traj["platoon_id"] == platoon_id])
    colors = _colors(len(members))
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10.0, 7.0), sharex=True, layout="constrained")
    for (vid, rows), color in zip(members, colors, strict=True):
        top.plot(rows["time_s"], rows["speed_mps"], color=color, lw=1.2, label=_label(vid, rows))
        if rows["spacing_error_m"].notna().any():
            bottom.plot(rows["time_s"], rows["spacing_error_m"], color=color, lw=1.2, label=vid)
    top.set_ylabel("speed [m/s]")
    top.set_title(f"Platoon {platoon_id}: speed of every member")
    bottom.set_ylabel("spacing error [m]\n(gap \u2212 desired gap)")
    bottom.set_xlabel("time [s]")
    bottom.set_title("Spacing error of every follower (positive: farther back than the policy)")
    if bottom.get_legend_handles_labels()[0]:
        bottom.axhline(0.0, color="k", lw=0.8)
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
        _legend_or_note(ax, "n/a: no follower with a spacing policy", loc="upper right")
    return fig


def time_space(traj: pd.DataFrame, platoon_id: str, path: Path) -> Path:
    """Distance along the route over time (a time-space diagram) of every member."""
    plt = _plt()
    members = _members(traj[traj["platoon_id"] == platoon_id])
    fig, ax = plt.subplots(figsize=(10.0, 6.0), layout="constrained")
    stop_label = "supervisor holds the vehicle for a signal"
    for (vid, rows), color in zip(members, _colors(len(members)), strict=True):
        ax.plot(rows["time_s"], rows["route_s_m"], color=color, lw=1.2, label=_label(vid, rows))
        stops = rows["supervisor"].astype(str) == "signal"
        if stops.any():
            ax.plot(rows["time_s"][stops], rows["route_s_m"][stops], ".", color="red", ms=2,
                    label=stop_label)  # fmt: skip
            stop_label = "_nolegend_"
    ax.set_xlabel("time [s]")
    ax.set_ylabel("distance along the route [m]")
    ax.set_title(f"Platoon {platoon_id}: time-space diagram (front bumpers)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    return _save(fig, path)


def string_stability(
    traj: pd.DataFrame, vehicles: pd.DataFrame, platoon_id: str, path: Path
) -> Path:
    """Acceleration of every member over time, and how it grows or shrinks along the
    platoon (RMS acceleration, peak spacing error and l2 gain per member)."""
    return _save(string_stability_figure(traj, vehicles, platoon_id), path)


def string_stability_figure(traj: pd.DataFrame, vehicles: pd.DataFrame, platoon_id: str) -> Any:
    """The figure of `string_stability`; the panel along the platoon says n/a when the
    platoon has no follower to compare with the member ahead."""
    plt = _plt()
    members = _members(traj[traj["platoon_id"] == platoon_id])
    fig, (left, right) = plt.subplots(
        1, 2, figsize=(12.0, 5.0), layout="constrained", gridspec_kw={"width_ratios": [2, 1]}
    )
    for (vid, rows), color in zip(members, _colors(len(members)), strict=True):
        left.plot(rows["time_s"], rows["accel_mps2"], color=color, lw=1.0, label=_label(vid, rows))
    left.set_xlabel("time [s]")
    left.set_ylabel("acceleration [m/s\u00b2]")
    left.set_title(f"Platoon {platoon_id}: acceleration of every member")
    left.grid(True, alpha=0.3)
    _legend_or_note(left, "n/a: no acceleration recorded", loc="upper right")
    mine = vehicles[vehicles["platoon_id"] == platoon_id].sort_values("member_index")
    if not (mine["member_index"] > 0).any():
        right.set_title("Along the platoon", fontsize=10)
        _not_available(right, "n/a: no follower,\nnothing to compare\nalong the platoon")
        return fig
    _along_platoon(right, mine)
    return fig


def _along_platoon(ax: Any, mine: pd.DataFrame) -> None:
    """Bars per member (RMS acceleration, peak spacing error; none where a member has no
    value) and each follower's acceleration l2 gain above them."""
    index = mine["member_index"].to_numpy()
    ax.bar(index - 0.2, mine["rms_accel_mps2"], width=0.4,
           label="RMS acceleration [m/s\u00b2]", color="tab:blue")  # fmt: skip
    ax.bar(index + 0.2, mine["max_abs_spacing_error_m"], width=0.4,
           label="peak |spacing error| [m]", color="tab:orange")  # fmt: skip
    gains = mine["accel_l2_gain"]
    top = float(np.nanmax([mine["rms_accel_mps2"].max(), mine["max_abs_spacing_error_m"].max(),
                           0.1]))  # fmt: skip
    for i, g in zip(index, gains, strict=True):
        if pd.notna(g):
            ax.text(i, top * 1.04, f"\u03b3={g:.2f}", ha="center", fontsize=8,
                    color="darkred" if g > 1 else "darkgreen")  # fmt: skip
    ax.set_ylim(0, top * 1.18)
    ax.set_xticks(index)
    ax.set_xlabel("member index (0 = leader)")
    ax.set_title("Along the platoon\n(\u03b3: acceleration l2 gain from the member ahead)",
                 fontsize=10)  # fmt: skip
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), fontsize=8, ncol=2)
    ax.grid(True, axis="y", alpha=0.3)


def scan_snapshot(npz: Path, path: Path) -> Path | None:
    """The saved laser scan drawn with `platoon_sumo.sensors.plot.plot_scan`."""
    from platoon_sumo.sensors.laser import LaserScan
    from platoon_sumo.sensors.plot import plot_scan

    if not npz.is_file():
        return None
    with np.load(npz) as data:
        meta = json.loads(str(data["meta"]))
        vid = meta.pop("vehicle_id")
        own, pred_id, pred = (meta.pop(k, None) for k in SNAPSHOT_MARKS)  # older runs: absent
        scan = LaserScan(ranges=data["ranges"], **meta)
        rects, segs = data["rectangles"], data["segments"]
    title = f"Laser scan of {vid} at t = {scan.stamp_s:.1f} s (obstacles as cast)"
    scanner = (own, vid) if own is not None else None
    predecessor = (pred, pred_id) if pred is not None and pred_id is not None else None
    return Path(
        plot_scan(scan, rects, segs if len(segs) else None, path, title=title,
                  scanner=scanner, predecessor=predecessor)
    )  # fmt: skip


#: Keys of `scan_snapshot.npz`'s meta that mark the scanning car and its predecessor.
SNAPSHOT_MARKS = ("scanner_row", "predecessor_id", "predecessor_row")


def compare_bars(table: pd.DataFrame, metrics: Sequence[tuple[str, str]], path: Path) -> Path:
    """One bar panel per metric, one bar per run."""
    return _save(compare_bars_figure(table, metrics), path)


def compare_bars_figure(table: pd.DataFrame, metrics: Sequence[tuple[str, str]]) -> Any:
    """The figure of `compare_bars`: a run without the metric gets "n/a" where its bar
    would be, a metric no run has an n/a panel (not bars of zero)."""
    plt = _plt()
    n = len(metrics)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 4.2), layout="constrained", squeeze=False)
    runs = table["run"].astype(str).tolist()
    colors = [plt.get_cmap("tab10")(i % 10) for i in range(len(runs))]
    for ax, (key, label) in zip(axes[0], metrics, strict=True):
        ax.set_title(label, fontsize=10)
        values = pd.to_numeric(table[key], errors="coerce") if key in table else None
        if values is None or values.isna().all():
            _not_available(ax, "n/a: no run has a value\n(gaps and gains need a\n"
                           "follower, spacing errors\na spacing policy)")  # fmt: skip
            continue
        ax.bar(range(len(runs)), values, color=colors)
        for i in np.flatnonzero(values.isna().to_numpy()):
            ax.text(i, 0.03, "n/a", ha="center", va="bottom", fontsize=9, color="0.4",
                    transform=ax.get_xaxis_transform())  # fmt: skip
        ax.set_xlim(-0.6, len(runs) - 0.4)  # every run's place, with or without a bar
        ax.set_xticks(range(len(runs)))
        ax.set_xticklabels(runs, rotation=20, ha="right", fontsize=8)
        ax.grid(True, axis="y", alpha=0.3)
        if key == "max_accel_l2_gain":
            ax.axhline(1.0, color="k", ls="--", lw=0.8)
    fig.suptitle("Run comparison (worst platoon of each run)")
    return fig


def compare_along(runs: Sequence[tuple[str, pd.DataFrame]], path: Path) -> Path:
    """Per-member acceleration l2 gain and RMS spacing error, one line per run."""
    return _save(compare_along_figure(runs), path)


def compare_along_figure(runs: Sequence[tuple[str, pd.DataFrame]]) -> Any:
    """The figure of `compare_along`; a panel no run has a value for says n/a."""
    plt = _plt()
    fig, (left, right) = plt.subplots(1, 2, figsize=(11.0, 4.5), layout="constrained")
    for i, (name, vehicles) in enumerate(runs):
        color = plt.get_cmap("tab10")(i % 10)
        for pid, rows in vehicles.groupby("platoon_id"):
            rows = rows.sort_values("member_index")
            label = name if vehicles["platoon_id"].nunique() == 1 else f"{name}: {pid}"
            for ax, key in ((left, "accel_l2_gain"), (right, "rms_spacing_error_m")):
                if rows[key].notna().any():  # a lone leader has neither
                    ax.plot(rows["member_index"], rows[key], "o-", color=color, label=label)
    if left.get_lines():
        left.axhline(1.0, color="k", ls="--", lw=0.8)
    left.set_title("Acceleration l2 gain from the member ahead (< 1: attenuates)", fontsize=10)
    left.set_ylabel("l2 gain [-]")
    right.set_title("RMS spacing error", fontsize=10)
    right.set_ylabel("RMS spacing error [m]")
    for ax in (left, right):
        ax.set_xlabel("member index (0 = leader)")
        ax.grid(True, alpha=0.3)
        if ax.get_lines():
            ax.xaxis.get_major_locator().set_params(integer=True)
        _legend_or_note(ax, "n/a: no follower in these runs")
    return fig


def compare_speeds(runs: Sequence[tuple[str, pd.DataFrame]], path: Path) -> Path:
    """Speed of the first and the last member of each run's first platoon over time."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(10.0, 5.0), layout="constrained")
    for i, (name, traj) in enumerate(runs):
        color = plt.get_cmap("tab10")(i % 10)
        first = sorted(traj["platoon_id"].unique())[0]
        members = _members(traj[traj["platoon_id"] == first])
        (lead_id, lead), (last_id, last) = members[0], members[-1]
        ax.plot(lead["time_s"], lead["speed_mps"], color=color, lw=1.0, ls="--",
                label=f"{name}: {lead_id} (first)")  # fmt: skip
        ax.plot(last["time_s"], last["speed_mps"], color=color, lw=1.4,
                label=f"{name}: {last_id} (last)")  # fmt: skip
    ax.set_xlabel("time [s]")
    ax.set_ylabel("speed [m/s]")
    ax.set_title("Speed of the first and last member of each run's platoon")
    ax.grid(True, alpha=0.3)
    _legend_or_note(ax, "n/a: no platoon vehicle in these runs")
    return _save(fig, path)


def _not_available(ax: Any, text: str) -> None:
    """`text` in the middle of an empty panel, without axes that suggest values: no
    value ticks, and no x ticks unless the x axis is shared with a panel that has data."""
    ax.set_yticks([])
    if len(ax.get_shared_x_axes().get_siblings(ax)) == 1:
        ax.set_xticks([])
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=10,
            color="0.4")  # fmt: skip


def _legend_or_note(ax: Any, note: str, loc: str = "best") -> None:
    """A legend of the lines drawn, or `note` in the middle when nothing was drawn."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc=loc, fontsize=8)
    else:
        _not_available(ax, note)
