"""A PNG snapshot of one laser scan among its obstacles, for debugging and papers."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from platoon_sumo.geometry import rectangle_corners
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.sensors.raycast import obstacle_arrays

#: A vehicle to mark: (its row in the rectangles, its id).
Marked = tuple[int, str]

SCANNER_COLOR = "#1d3557"
PREDECESSOR_COLOR = "#2a9d8f"


def plot_scan(
    scan: LaserScan,
    rectangles: ArrayLike | None = None,
    segments: ArrayLike | None = None,
    path: str | os.PathLike[str] = "laser_scan.png",
    title: str | None = None,
    dpi: int = 150,
    scanner: Marked | None = None,
    predecessor: Marked | None = None,
) -> str:
    """Draw obstacles, rays, hit points and the sensor pose; write a PNG; return its path.

    matplotlib is imported here with the Agg backend so importing the package never
    touches a display or picks a backend for the caller.
    """
    fig = scan_figure(scan, rectangles, segments, title, scanner, predecessor)
    import matplotlib.pyplot as plt  # after scan_figure chose the Agg backend

    try:
        fig.savefig(os.fspath(path), dpi=dpi)
    finally:
        plt.close(fig)
    return os.fspath(path)


def scan_figure(
    scan: LaserScan,
    rectangles: ArrayLike | None = None,
    segments: ArrayLike | None = None,
    title: str | None = None,
    scanner: Marked | None = None,
    predecessor: Marked | None = None,
) -> Any:
    """The figure of `plot_scan`: every vehicle as its outline, the scanning car
    (`scanner`) filled and its `predecessor` highlighted and named, so the reader sees
    which returns come from the car being followed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    rects, segs = obstacle_arrays(rectangles, segments)
    ox, oy, heading = scan.origin_x_m, scan.origin_y_m, scan.heading_rad
    world = heading + scan.angles
    r = scan.ranges
    hit = np.isfinite(r)
    # rays: to the hit or to range_max (no return); dropouts and too-close are not drawn
    reach = np.where(hit, r, scan.range_max)
    drawn = hit | np.isposinf(r)
    ends = np.column_stack((ox + reach * np.cos(world), oy + reach * np.sin(world)))

    fig, ax = plt.subplots(figsize=(7.0, 7.0), layout="constrained")
    _draw_vehicles(ax, rects, scanner, predecessor)
    if segs.shape[0]:
        ax.add_collection(
            LineCollection(
                list(segs.reshape(-1, 2, 2)), colors="#444444", linewidths=2.0, label="walls"
            )
        )
    starts = np.broadcast_to([ox, oy], ends.shape)
    rays = np.stack((starts, ends), axis=1)[drawn]
    ax.add_collection(
        LineCollection(list(rays), colors="#f4a261", linewidths=0.3, alpha=0.5, label="rays")
    )
    pts = ends[hit]
    ax.plot(pts[:, 0], pts[:, 1], ".", color="#d62828", markersize=2.5, label="hits")
    arrow = 0.15 * scan.range_max
    ax.annotate(
        "",
        xy=(ox + arrow * np.cos(heading), oy + arrow * np.sin(heading)),
        xytext=(ox, oy),
        arrowprops={"arrowstyle": "->", "color": SCANNER_COLOR, "lw": 1.5},
    )
    ax.plot([ox], [oy], "o", color=SCANNER_COLOR, markersize=6, label="sensor")
    counts = (
        f"{int(hit.sum())} hits, {int(np.isposinf(r).sum())} no return, "
        f"{int(np.isneginf(r).sum())} too close, {int(np.isnan(r).sum())} dropouts"
    )
    ax.set_title(f"{title or f'Laser scan at t = {scan.stamp_s:.2f} s'}\n{counts}", fontsize=10)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="box")
    span = scan.range_max * 1.05
    ax.set_xlim(ox - span, ox + span)
    ax.set_ylim(oy - span, oy + span)
    ax.grid(True, linewidth=0.3, alpha=0.5)
    ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    return fig


def _draw_vehicles(
    ax: Any, rects: np.ndarray, scanner: Marked | None, predecessor: Marked | None
) -> None:
    """Outlines of all vehicles; the scanner filled, the predecessor filled and named."""
    from matplotlib.patches import Polygon

    if not rects.shape[0]:
        return
    polys = rectangle_corners(rects)
    marked = {m[0] for m in (scanner, predecessor) if m is not None}
    label = "vehicles (outlines)"
    for row in sorted(set(range(len(polys))) - marked):
        ax.add_patch(Polygon(polys[row], closed=True, fill=False, edgecolor="#2f4b66",
                             linewidth=1.0, label=label))  # fmt: skip
        label = "_nolegend_"
    for mark, color, role in ((scanner, SCANNER_COLOR, "scanning car"),
                              (predecessor, PREDECESSOR_COLOR, "predecessor")):  # fmt: skip
        if mark is None:
            continue
        row, vid = mark
        ax.add_patch(Polygon(polys[row], closed=True, facecolor=color, edgecolor=color,
                             alpha=0.75, linewidth=1.5, label=f"{role} {vid}",
                             zorder=3))  # fmt: skip
        if role == "predecessor":
            x, y = rects[row, 0], rects[row, 1]
            ax.annotate(vid, xy=(x, y), xytext=(0, 14), textcoords="offset points",
                        ha="center", fontsize=8, color=color, fontweight="bold",
                        arrowprops={"arrowstyle": "-", "color": color})  # fmt: skip
