"""Per-follower platoon metrics computed from a run's trajectory table.

- `in_view_share` [-]: share of the follower's scans, from the first one that saw its
  predecessor on, in which at least one ray returns from the predecessor.
- `lost_scans` [-]: the number of those scans with no ray on the predecessor.
- `min_gap_m` [m]: smallest `gap_to_predecessor_m` (front-bumper centre to the
  predecessor's rear-bumper centre).
- `rms_spacing_error_m` [m]: root mean square of `gap_to_predecessor_m - desired_gap_m`
  (followers whose controller declares a spacing policy).
- `max_lateral_deviation_m`, `rms_lateral_deviation_m` [m]: distance from the follower's
  front bumper to the polyline its predecessor's front bumper drew (the predecessor's
  path), where the follower is alongside that path (not behind its start or past its end).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
import shapely


def follower_metrics(trajectories: pd.DataFrame) -> dict[str, dict[str, dict[str, Any]]]:
    """{platoon id: {follower id: metrics}} for every member that had a predecessor."""
    result: dict[str, dict[str, dict[str, Any]]] = {}
    paths: dict[str, shapely.LineString] = {
        str(vid): shapely.LineString(group[["x_m", "y_m"]].to_numpy())
        for vid, group in trajectories.groupby("vehicle_id", sort=True)
        if len(group) >= 2
    }
    followers = trajectories[trajectories["predecessor_id"].notna()]
    for (platoon, vid), rows in followers.groupby(["platoon_id", "vehicle_id"], sort=True):
        result.setdefault(str(platoon), {})[str(vid)] = _one_follower(rows, paths)
    return result


def _one_follower(rows: pd.DataFrame, paths: dict[str, shapely.LineString]) -> dict[str, Any]:
    out: dict[str, Any] = {"steps": len(rows)}
    scans = rows["predecessor_rays"].dropna()
    seen = np.flatnonzero(scans.to_numpy() > 0)
    if len(scans) and len(seen):
        after = scans.to_numpy()[seen[0] :]
        out["in_view_share"] = float(np.mean(after > 0))
        out["lost_scans"] = int(np.count_nonzero(after == 0))
    else:
        out["in_view_share"] = 0.0 if len(scans) else None
        out["lost_scans"] = len(scans)
    gaps = rows["gap_to_predecessor_m"].dropna()
    out["min_gap_m"] = float(gaps.min()) if len(gaps) else None
    error = (rows["gap_to_predecessor_m"] - rows["desired_gap_m"]).dropna()
    out["rms_spacing_error_m"] = float(np.sqrt(np.mean(error**2))) if len(error) else None
    deviations = []
    for pred, part in rows.groupby("predecessor_id", sort=False):
        path = paths.get(str(pred))
        if path is not None:
            points = shapely.points(part[["x_m", "y_m"]].to_numpy())
            # Only where the follower is alongside the path: before its start (queued
            # behind the predecessor's first position) or past its end there is no path.
            along = shapely.line_locate_point(path, points)
            beside = (along > 1e-9) & (along < path.length - 1e-9)
            deviations.append(shapely.distance(points[beside], path))
    if deviations:
        d = np.concatenate(deviations)
        out["max_lateral_deviation_m"] = float(d.max())
        out["rms_lateral_deviation_m"] = float(math.sqrt(np.mean(d**2)))
    return out
