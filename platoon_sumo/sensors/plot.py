"""A PNG snapshot of one laser scan among its obstacles, for debugging and papers."""

from __future__ import annotations

import os

import numpy as np
from numpy.typing import ArrayLike

from platoon_sumo.geometry import rectangle_corners
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.sensors.raycast import obstacle_arrays


def plot_scan(
    scan: LaserScan,
    rectangles: ArrayLike | None = None,
    segments: ArrayLike | None = None,
    path: str | os.PathLike[str] = "laser_scan.png",
    title: str | None = None,
    dpi: int = 150,
) -> str:
    """Draw obstacles, rays, hit points and the sensor pose; write a PNG; return its path.

    matplotlib is imported here with the Agg backend so importing the package never
    touches a display or picks a backend for the caller.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

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
    try:
        if rects.shape[0]:
            polys = rectangle_corners(rects)
            ax.add_collection(
                PolyCollection(
                    list(polys),
                    facecolors="#c9d6e3",
                    edgecolors="#2f4b66",
                    linewidths=1.0,
                    label="vehicles",
                )
            )
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
            arrowprops={"arrowstyle": "->", "color": "#1d3557", "lw": 1.5},
        )
        ax.plot([ox], [oy], "o", color="#1d3557", markersize=6, label="sensor")
        counts = (
            f"{int(hit.sum())} hits, {int(np.isposinf(r).sum())} no return, "
            f"{int(np.isneginf(r).sum())} too close, {int(np.isnan(r).sum())} dropouts"
        )
        ax.set_title(title or f"Laser scan at t = {scan.stamp_s:.2f} s\n{counts}", fontsize=10)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_aspect("equal", adjustable="box")
        span = scan.range_max * 1.05
        ax.set_xlim(ox - span, ox + span)
        ax.set_ylim(oy - span, oy + span)
        ax.grid(True, linewidth=0.3, alpha=0.5)
        ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
        fig.savefig(os.fspath(path), dpi=dpi)
    finally:
        plt.close(fig)
    return os.fspath(path)
