"""Platoon metrics: per-step formulas, bounded-memory summaries, SUMO's own outputs.

- `kernels`: one step's formulas (spacing error, time gap, time to collision, jerk,
  deviation from the predecessor's path, l2 gain).
- `stats`: `RunStats`, per-vehicle and per-platoon summaries accumulated step by step
  (the recorder feeds it online; `summarise_trajectories` feeds it a table).
- `string_stability`: frequency responses from member to member, and the verdict.
- `sumo_outputs`: tripinfo (with emissions), summary and edgeData read from SUMO.

Every metric is defined in docs/metrics.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from platoon_sumo.events import Event, EventKind
from platoon_sumo.metrics.kernels import Trails
from platoon_sumo.metrics.stats import RunStats, given, table_steps

__all__ = ["RunStats", "follower_metrics", "read_events", "summarise_trajectories"]


def summarise_trajectories(
    trajectories: pd.DataFrame,
    planned: Mapping[str, int] | None = None,
    start_s: float = 0.0,
    events: pd.DataFrame | None = None,
    limits: Mapping[str, tuple[float, float, float]] | None = None,
) -> RunStats:
    """Feed a trajectory table (and the run's `events.csv`, for the event counts) to
    `RunStats`, step by step: the same numbers the run computed online (given the
    platoons' vehicle `limits`, as `RunStats` takes them).

    Tables without `lateral_deviation_m` (hand-built ones) get it by replaying each
    predecessor's path as the recorder does (every position kept).
    """
    replay = "lateral_deviation_m" not in trajectories.columns
    trails = Trails()
    stats = RunStats(planned, start_s, limits)
    for time_s, columns in table_steps(trajectories):
        if replay:
            xs, ys = columns["x_m"].astype(float), columns["y_m"].astype(float)
            ids = [str(vid) for vid in columns["vehicle_id"]]
            trails.append(ids, xs, ys, np.zeros(len(ids)))
            preds = columns.get("predecessor_id", [None] * len(xs))
            of = [str(p) if given(p) else "" for p in preds]
            columns["lateral_deviation_m"] = trails.deviation(of, xs, ys)
        stats.add_step(time_s, columns)
    if events is not None:
        stats.add_events(read_events(events))
    return stats


def read_events(table: pd.DataFrame) -> list[Event]:
    """Events from an `events.csv` table (as read by pandas)."""
    text = table.astype(object).where(table.notna(), "")
    return [
        Event(float(r.time_s), EventKind(r.kind), str(r.vehicle_id), str(r.other_id),
              str(r.platoon_id), str(r.detail), str(getattr(r, "at_fault", "")))
        for r in text.itertuples(index=False)
    ]  # fmt: skip


def follower_metrics(trajectories: pd.DataFrame) -> dict[str, dict[str, dict[str, Any]]]:
    """{platoon id: {follower id: metrics}} for every member that had a predecessor (the
    `followers` entry of summary.json)."""
    return summarise_trajectories(trajectories).followers()
