"""Step hooks that write a run's tables: the platoon trajectories, in bounded chunks.

`TrajectoryRecorder` writes one row per platoon vehicle per step (columns and units in
`TRAJECTORY_COLUMNS` and docs/outputs.md) as CSV or Parquet, appending every
`chunk_rows` rows, and feeds the same step, as columns, to a `RunStats` for the run's
summaries. A step's rows are built column by column over all platoon vehicles.
Its memory is bounded: one chunk of rows, per-vehicle running sums, and per-vehicle
trails of recent positions (pruned as the follower passes them, capped in length).

`ScanSnapshot` keeps one follower's laser scan (with the obstacles it saw) for the
report's scan figure.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from platoon_sumo.events import EVENT_COLUMNS, event_row
from platoon_sumo.loop.context import RunContext, RunOutcome, StepHook, StepRecord
from platoon_sumo.metrics.kernels import (
    PathTrail,
    jerk_mps3,
    spacing_error_m,
    time_gap_s,
    time_to_collision_s,
)
from platoon_sumo.metrics.stats import RunStats
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.sensors.v2v import V2VInbox

#: Column name -> type (f float, i integer, s text); the table's columns in order.
COLUMN_TYPES: dict[str, str] = {
    "time_s": "f", "vehicle_id": "s", "platoon_id": "s", "member_index": "i", "role": "s",
    "x_m": "f", "y_m": "f", "yaw_rad": "f", "speed_mps": "f", "accel_mps2": "f",
    "jerk_mps3": "f", "cmd_speed_mps": "f", "cmd_yaw_rate_radps": "f", "cmd_heading_rad": "f",
    "executed_speed_mps": "f", "route_s_m": "f", "lateral_offset_m": "f",
    "lane_width_m": "f", "lane_id": "s", "signal_tls": "s", "signal_state": "s",
    "signal_distance_m": "f", "ahead_id": "s", "ahead_gap_m": "f", "predecessor_id": "s",
    "predecessor_speed_mps": "f", "gap_to_predecessor_m": "f", "measured_gap_m": "f",
    "desired_gap_m": "f", "spacing_error_m": "f", "time_gap_s": "f", "ttc_s": "f",
    "lateral_deviation_m": "f", "predecessor_rays": "i", "predecessor_in_view": "i",
    "supervisor": "s",
    "controller_mode": "s",
}  # fmt: skip
TRAJECTORY_COLUMNS = tuple(COLUMN_TYPES)
FORMATS = ("csv", "parquet")
#: Trail points are kept every this share of the vehicle's length, at most this many.
TRAIL_SPACING_LENGTHS = 0.05
TRAIL_MAX_POINTS = 5000


class TableWriter:
    """Appends chunks of columns (lists or arrays in the order of `column_types`, by
    default `TRAJECTORY_COLUMNS`; None for an empty cell) to a CSV or Parquet file,
    through Arrow: its CSV writer formats a chunk's floats in compiled code (the csv
    module's float formatting, about 0.5 µs a number, was the loop's largest single
    cost); the same shortest round-trip digits, integral floats without ".0", text
    quoted."""

    def __init__(self, path: Path, fmt: str = "csv", column_types: dict[str, str] = COLUMN_TYPES):
        if fmt not in FORMATS:
            raise ValueError(f"unknown table format {fmt!r}; expected one of {FORMATS}")
        self.path, self.fmt = path, fmt
        self._parquet: pq.ParquetWriter | None = None
        types = {"f": pa.float64(), "i": pa.int64(), "s": pa.string()}
        self._schema = pa.schema([(c, types[t]) for c, t in column_types.items()])

    def open(self) -> None:
        if self.fmt == "csv":
            with self.path.open("w", newline="") as f:
                csv.writer(f).writerow(self._schema.names)
        else:
            self._parquet = pq.ParquetWriter(str(self.path), self._schema)

    def write(self, columns: Sequence[Any]) -> None:
        """Append one chunk: a list or array per column, in the table's order."""
        if not columns or not len(columns[0]):
            return
        schema = self._schema
        arrays = [pa.array(col, type=schema.field(i).type) for i, col in enumerate(columns)]
        table = pa.Table.from_arrays(arrays, schema=schema)
        if self._parquet is not None:
            self._parquet.write_table(table)
            return
        with self.path.open("ab") as f:
            pa_csv.write_csv(table, f, _CSV_OPTIONS)

    def close(self) -> None:
        if self._parquet is not None:
            self._parquet.close()
            self._parquet = None


_CSV_OPTIONS = pa_csv.WriteOptions(include_header=False)


class TrajectoryRecorder(StepHook):
    """Appends one row per platoon vehicle per step; flushes every `chunk_rows` rows.

    `stats` (if given) receives every step's columns and the step's collisions and
    red-light violations. `write=False` keeps only the statistics (no table).
    """

    def __init__(
        self,
        path: Path,
        chunk_rows: int = 20_000,
        fmt: str = "csv",
        stats: RunStats | None = None,
        write: bool = True,
    ):
        self.path = path
        self.chunk_rows = chunk_rows
        self.writer = TableWriter(path, fmt) if write else None
        self.stats = stats
        self._steps: list[list[Sequence[Any]]] = []
        """The steps' columns not yet written, a step appended whole in one call: an
        interrupt (Ctrl-C) between the columns once left them of unequal lengths, and
        the end's flush failed and lost every row still in memory."""
        self._buffered_rows = 0
        """How many rows `_steps` holds."""
        self.rows_written = 0
        self._accel: dict[str, float] = {}
        self._trails: dict[str, PathTrail] = {}
        self._dt_s = 0.0

    def on_start(self, run: RunContext) -> None:
        self._dt_s = run.dt_s
        if self.writer is not None:
            self.writer.open()

    def on_step(self, record: StepRecord) -> None:
        vehicles = record.vehicles
        for v in vehicles:  # every trail first, then measure against them
            trail = self._trails.get(v.id)
            if trail is None:
                spacing = TRAIL_SPACING_LENGTHS * v.length_m
                trail = self._trails[v.id] = PathTrail(spacing, TRAIL_MAX_POINTS)
            trail.append(v.front_x_m, v.front_y_m)
        columns = self._columns(record)
        followed = {v.predecessor_id for v in vehicles}
        for vid, trail in self._trails.items():
            if vid not in followed:
                trail.keep_last(2)  # nobody measures against it: keep only its end
        present = {v.id for v in vehicles}
        for gone in set(self._trails) - present:  # arrived: forget (bounded memory)
            del self._trails[gone]
            self._accel.pop(gone, None)
        if self.stats is not None:
            self.stats.add_step(record.time_s, columns)
            self.stats.add_events(record.events)
            for v in vehicles:
                inboxes = [m for m in v.sensors.values() if isinstance(m, V2VInbox)]
                if inboxes:  # several channels: their sums
                    self.stats.add_v2v(
                        v.id,
                        sum(i.sent_total for i in inboxes),
                        sum(i.received_total for i in inboxes),
                        sum(i.lost_total for i in inboxes),
                    )
        if self.writer is not None and vehicles:
            if self.rows_written == 0 and not self._steps:
                assert tuple(columns) == TRAJECTORY_COLUMNS, "columns out of order"
            self._steps.append(list(columns.values()))
            self._buffered_rows += len(vehicles)
            if self._buffered_rows >= self.chunk_rows:
                self.flush()

    def _columns(self, record: StepRecord) -> dict[str, Sequence[Any]]:
        """The step's rows as columns (in `TRAJECTORY_COLUMNS` order; docs/outputs.md
        defines each): the records' own fields taken in one transpose, the derived ones
        one list comprehension a column."""
        vs = record.vehicles
        if not vs:
            return {name: [] for name in TRAJECTORY_COLUMNS}
        (
            ids, platoon_ids, member_indices, roles, _, _, yaws, xs, ys, speeds, accels, _,
            route_s, lateral, lane_widths, commands, executed, supervisor, signals, aheads,
            pred_ids, gaps, pred_rays, _,
        ) = zip(*vs, strict=True)  # fmt: skip
        lane_ids, index = record.world.lane_ids, record.world.index
        speed_of = dict(zip(ids, speeds, strict=True))
        has_pred = [p is not None for p in pred_ids]
        pred_speed = [speed_of.get(p or "") for p in pred_ids]
        telemetry = [c.telemetry for c in commands]
        desired = [
            t.gap_policy.desired_m(v) if h and t is not None and t.gap_policy is not None else None
            for v, t, h in zip(speeds, telemetry, has_pred, strict=True)
        ]
        previous_accel = self._accel
        jerk = [
            jerk_mps3(a, previous_accel.get(vid), self._dt_s)
            for vid, a in zip(ids, accels, strict=True)
        ]
        previous_accel.update(zip(ids, accels, strict=True))
        trails = self._trails
        rays = [r if h else None for r, h in zip(pred_rays, has_pred, strict=True)]
        time_s = round(record.time_s, 6)
        return {
            "time_s": [time_s] * len(vs),
            "vehicle_id": ids,
            "platoon_id": platoon_ids,
            "member_index": member_indices,
            "role": roles,
            "x_m": xs,
            "y_m": ys,
            "yaw_rad": yaws,
            "speed_mps": speeds,
            "accel_mps2": accels,
            "jerk_mps3": jerk,
            "cmd_speed_mps": [_finite(c.speed_mps) for c in commands],
            "cmd_yaw_rate_radps": [c.yaw_rate_radps for c in commands],
            "cmd_heading_rad": [c.heading_rad for c in commands],
            "executed_speed_mps": [_finite(c.speed_mps) for c in executed],
            "route_s_m": route_s,
            "lateral_offset_m": lateral,
            "lane_width_m": lane_widths,
            "lane_id": [lane_ids[i] if (i := index.get(vid)) is not None else None for vid in ids],
            "signal_tls": [s.tls_id if s else None for s in signals],
            "signal_state": [s.state if s else None for s in signals],
            "signal_distance_m": [s.distance_m if s else None for s in signals],
            "ahead_id": [a.vehicle_id if a else None for a in aheads],
            "ahead_gap_m": [a.gap_m if a else None for a in aheads],
            "predecessor_id": pred_ids,
            "predecessor_speed_mps": pred_speed,
            "gap_to_predecessor_m": gaps,
            "measured_gap_m": [
                t.measured_gap_m if h and t is not None else None
                for t, h in zip(telemetry, has_pred, strict=True)
            ],
            "desired_gap_m": desired,
            "spacing_error_m": [spacing_error_m(g, d) for g, d in zip(gaps, desired, strict=True)],
            "time_gap_s": [
                time_gap_s(g, v) if h else None
                for g, v, h in zip(gaps, speeds, has_pred, strict=True)
            ],
            "ttc_s": [
                time_to_collision_s(g, v, p)
                for g, v, p in zip(gaps, speeds, pred_speed, strict=True)
            ],
            "lateral_deviation_m": [
                trail.deviation(x, y)
                if h and (trail := trails.get(p)) is not None
                else None
                for x, y, p, h in zip(xs, ys, pred_ids, has_pred, strict=True)
            ],
            "predecessor_rays": rays,
            "predecessor_in_view": [int(r > 0) if r is not None else None for r in rays],
            "supervisor": [s or None for s in supervisor],
            "controller_mode": [t.mode or None if t is not None else None for t in telemetry],
        }  # fmt: skip

    def flush(self) -> None:
        steps = self._steps
        if steps and self.writer is not None:
            columns = [
                list(itertools.chain.from_iterable(step[k] for step in steps))
                for k in range(len(TRAJECTORY_COLUMNS))
            ]
            self.writer.write(columns)
            self.rows_written += len(columns[0])
            self._steps, self._buffered_rows = [], 0

    def on_end(self, outcome: RunOutcome) -> None:
        self.flush()
        if self.writer is not None:
            self.writer.close()


class EventWriter(StepHook):
    """Writes the run's events to `events.csv` as they happen (see docs/metrics.md)."""

    def __init__(self, path: Path):
        self.path = path
        self._file: Any = None
        self._csv: Any = None

    def on_start(self, run: RunContext) -> None:
        self._file = self.path.open("w", newline="")
        self._csv = csv.writer(self._file)
        self._csv.writerow(EVENT_COLUMNS)

    def on_step(self, record: StepRecord) -> None:
        if record.events:
            self._csv.writerows(event_row(e) for e in record.events)

    def on_end(self, outcome: RunOutcome) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


@dataclass(frozen=True)
class _Marks:
    """The scanning vehicle and its predecessor, with their rows in the footprints."""

    vehicle_id: str
    vehicle_row: int | None
    predecessor_id: str | None
    predecessor_row: int | None


class ScanSnapshot(StepHook):
    """Keeps one laser scan for the report, with the footprints (its own and its
    predecessor's marked) and wall segments it was cast against; `save` writes an .npz
    that `platoon_sumo.report` draws with `plot_scan`.

    The vehicle is `vehicle_id`, else the first follower with a sensor (else any vehicle
    with one). The scan is its first one at or after `at_s`; with `at_s` None, the one
    closest to the middle of the vehicle's scans that saw its predecessor (kept at the
    1st, 2nd, 4th, 8th, ... such scan: two scans in memory, whatever the run's length).
    """

    def __init__(self, at_s: float | None = None, vehicle_id: str | None = None):
        self.at_s = at_s
        self.vehicle_id = vehicle_id
        self._kept: list[tuple[int, LaserScan, np.ndarray, _Marks]] = []
        self._count = 0
        self.segments: np.ndarray | None = None
        self.frozen = False

    def on_start(self, run: RunContext) -> None:
        self.segments = run.static_segments

    def on_step(self, record: StepRecord) -> None:
        sensed, rects_seen = record.sensed_world, record.sensed_footprints
        if self.frozen or sensed is None or rects_seen is None:
            return
        candidates = [v for v in record.vehicles if v.scan is not None]
        if self.vehicle_id is not None:
            candidates = [v for v in candidates if v.id == self.vehicle_id]
        else:
            candidates.sort(key=lambda v: (v.member_index != 1, v.member_index, v.id))
        if not candidates:
            return
        v = candidates[0]
        if self.vehicle_id is None:
            self.vehicle_id = v.id
        scan = v.scan
        if scan is None or abs(scan.stamp_s - sensed.time_s) > 1e-9:
            return  # not a new scan of this step
        pred = v.predecessor_id
        marks = _Marks(v.id, sensed.index.get(v.id), pred, sensed.index.get(pred or ""))
        rects = rects_seen
        if self.at_s is not None:
            self._kept = [(0, scan, rects, marks)]
            self.frozen = record.time_s >= self.at_s
            return
        if not v.predecessor_rays:
            return
        self._count += 1
        if self._count & (self._count - 1) == 0:  # a power of two
            self._kept = [*self._kept[-1:], (self._count, scan, rects, marks)]

    def chosen(self) -> tuple[LaserScan, np.ndarray, _Marks] | None:
        if not self._kept:
            return None
        middle = self._count / 2
        _, scan, rects, marks = min(self._kept, key=lambda k: abs(k[0] - middle))
        return scan, rects, marks

    def save(self, path: Path) -> Path | None:
        """Write the scan and the obstacles within its range; None if no scan was kept."""
        chosen = self.chosen()
        if chosen is None:
            return None
        scan, rects, marks = chosen
        reach = scan.range_max + 10.0
        near = np.hypot(rects[:, 0] - scan.origin_x_m, rects[:, 1] - scan.origin_y_m) < reach
        kept_row = np.cumsum(near) - 1  # a row's index among the rows kept

        def row(i: int | None) -> int | None:
            return int(kept_row[i]) if i is not None and near[i] else None

        segs = self.segments if self.segments is not None else np.zeros((0, 4))
        if len(segs):
            mid_x, mid_y = (segs[:, 0] + segs[:, 2]) / 2, (segs[:, 1] + segs[:, 3]) / 2
            half = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1]) / 2
            segs = segs[np.hypot(mid_x - scan.origin_x_m, mid_y - scan.origin_y_m) < reach + half]
        fields = ("angle_min", "angle_max", "angle_increment", "time_increment", "scan_time",
                  "range_min", "range_max", "origin_x_m", "origin_y_m", "heading_rad",
                  "stamp_s")  # fmt: skip
        meta: dict[str, Any] = {k: getattr(scan, k) for k in fields}
        meta["vehicle_id"] = marks.vehicle_id
        meta["scanner_row"] = row(marks.vehicle_row)
        meta["predecessor_id"] = marks.predecessor_id
        meta["predecessor_row"] = row(marks.predecessor_row)
        with path.open("wb") as f:
            np.savez_compressed(
                f, ranges=scan.ranges, rectangles=rects[near], segments=segs,
                meta=np.array(json.dumps(meta)),
            )  # fmt: skip
        return path
