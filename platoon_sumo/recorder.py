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
    FloatArray,
    Trails,
    desired_gap_m,
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
    default `TRAJECTORY_COLUMNS`; None or NaN for an empty cell) to a CSV or Parquet file,
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
        arrays = [
            pa.array(col, type=schema.field(i).type, from_pandas=True)  # NaN: an empty cell
            for i, col in enumerate(columns)
        ]
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
        self._steps: list[list[Sequence[Any] | FloatArray]] = []
        """The steps' columns not yet written, a step appended whole in one call: an
        interrupt (Ctrl-C) between the columns once left them of unequal lengths, and
        the end's flush failed and lost every row still in memory."""
        self._buffered_rows = 0
        """How many rows `_steps` holds."""
        self.rows_written = 0
        self._accel: dict[str, float] = {}
        self._trails = Trails(TRAIL_MAX_POINTS)
        self._dt_s = 0.0

    def on_start(self, run: RunContext) -> None:
        self._dt_s = run.dt_s
        if self.writer is not None:
            self.writer.open()

    def on_step(self, record: StepRecord) -> None:
        vc = record.columns
        trails = self._trails  # every trail first, then measure against them
        trails.append(vc.id, vc.front_x_m, vc.front_y_m, TRAIL_SPACING_LENGTHS * vc.length_m)
        columns = self._columns(record)
        followed = set(vc.predecessor_id)
        # nobody measures against these: keep only their end
        trails.keep_last(2, [vid for vid in trails.ids() if vid not in followed])
        gone = set(trails.ids()).difference(vc.id)
        trails.forget(gone)  # arrived: forget (bounded memory)
        for vid in gone:
            self._accel.pop(vid, None)
        if self.stats is not None:
            self.stats.add_step(record.time_s, columns)
            self.stats.add_events(record.events)
            for vid, sensors in zip(vc.id, vc.sensors, strict=True):
                inboxes = [m for m in sensors.values() if isinstance(m, V2VInbox)]
                if inboxes:  # several channels: their sums
                    self.stats.add_v2v(
                        vid,
                        sum(i.sent_total for i in inboxes),
                        sum(i.received_total for i in inboxes),
                        sum(i.lost_total for i in inboxes),
                    )
        if self.writer is not None and len(vc):
            if self.rows_written == 0 and not self._steps:
                assert tuple(columns) == TRAJECTORY_COLUMNS, "columns out of order"
            self._steps.append(list(columns.values()))
            self._buffered_rows += len(vc)
            if self._buffered_rows >= self.chunk_rows:
                self.flush()

    def _columns(self, record: StepRecord) -> dict[str, Sequence[Any] | FloatArray]:
        """The step's rows as columns (in `TRAJECTORY_COLUMNS` order; docs/outputs.md
        defines each): numbers as float arrays, NaN for an empty cell (the metrics of
        `metrics.kernels`, over all vehicles at once), the rest as sequences."""
        vc = record.columns
        n = len(vc)
        if not n:
            return {name: [] for name in TRAJECTORY_COLUMNS}
        ids, speeds, pred_ids = vc.id, vc.speed_mps, vc.predecessor_id
        has_pred = np.array([p is not None for p in pred_ids], dtype=bool)
        row_of = dict(zip(ids, range(n), strict=True))
        pred_row = np.array([row_of.get(p or "", -1) for p in pred_ids], dtype=np.intp)
        pred_speed = np.where(pred_row >= 0, speeds[pred_row], np.nan)
        gaps = np.array(vc.gap_to_predecessor_m, dtype=np.float64)
        # the commands' fields in one pass: (speed, yaw rate, heading, measured gap,
        # mode, the spacing policy's standstill gap and time gap)
        cmd_speed, cmd_yaw_rate, cmd_heading, measured, modes, standstill, time_gap = zip(
            *[
                (c.speed_mps, c.yaw_rate_radps, c.heading_rad, None, None, *_NO_POLICY)
                if (t := c.telemetry) is None
                else (c.speed_mps, c.yaw_rate_radps, c.heading_rad, t.measured_gap_m)
                + (t.mode or None,)
                + (_NO_POLICY if (g := t.gap_policy) is None else (g.standstill_m, g.time_gap_s))
                for c in vc.command
            ],
            strict=True,
        )
        desired = desired_gap_m(
            np.where(has_pred, _floats(standstill), np.nan),
            np.where(has_pred, _floats(time_gap), np.nan),
            speeds,
        )
        previous = self._accel
        accels = vc.accel_mps2
        before = np.array([previous.get(vid, np.nan) for vid in ids], dtype=np.float64)
        jerk = jerk_mps3(accels, before, self._dt_s)
        previous.update(zip(ids, accels.tolist(), strict=True))
        lateral = np.full(n, np.nan)
        follower = np.flatnonzero(has_pred)
        lateral[follower] = self._trails.deviation(
            [pred_ids[k] or "" for k in follower.tolist()],
            vc.front_x_m[follower],
            vc.front_y_m[follower],
        )
        rays = [
            r if h else None for r, h in zip(vc.predecessor_rays, has_pred.tolist(), strict=True)
        ]
        lane_ids, index = record.world.lane_ids, record.world.index
        tls, state, distance = zip(
            *[(s.tls_id, s.state, s.distance_m) if s else _NO_SIGNAL for s in vc.signal],
            strict=True,
        )
        ahead_id, ahead_gap = zip(
            *[(a.vehicle_id, a.gap_m) if a else _NO_AHEAD for a in vc.vehicle_ahead], strict=True
        )
        return {
            "time_s": np.full(n, round(record.time_s, 6)),
            "vehicle_id": ids,
            "platoon_id": vc.platoon_id,
            "member_index": vc.member_index,
            "role": vc.role,
            "x_m": vc.front_x_m,
            "y_m": vc.front_y_m,
            "yaw_rad": vc.yaw_rad,
            "speed_mps": speeds,
            "accel_mps2": accels,
            "jerk_mps3": jerk,
            "cmd_speed_mps": _finite(cmd_speed),
            "cmd_yaw_rate_radps": _floats(cmd_yaw_rate),
            "cmd_heading_rad": _floats(cmd_heading),
            "executed_speed_mps": _finite([c.speed_mps for c in vc.executed]),
            "route_s_m": vc.route_s_m,
            "lateral_offset_m": vc.lateral_offset_m,
            "lane_width_m": vc.lane_width_m,
            "lane_id": [lane_ids[i] if (i := index.get(vid)) is not None else None for vid in ids],
            "signal_tls": tls,
            "signal_state": state,
            "signal_distance_m": _floats(distance),
            "ahead_id": ahead_id,
            "ahead_gap_m": _floats(ahead_gap),
            "predecessor_id": pred_ids,
            "predecessor_speed_mps": pred_speed,
            "gap_to_predecessor_m": gaps,
            "measured_gap_m": np.where(has_pred, _floats(measured), np.nan),
            "desired_gap_m": desired,
            "spacing_error_m": spacing_error_m(gaps, desired),
            "time_gap_s": np.where(has_pred, time_gap_s(gaps, speeds), np.nan),
            "ttc_s": time_to_collision_s(gaps, speeds, pred_speed),
            "lateral_deviation_m": lateral,
            "predecessor_rays": rays,
            "predecessor_in_view": [int(r > 0) if r is not None else None for r in rays],
            "supervisor": [s or None for s in vc.supervisor_state],
            "controller_mode": modes,
        }  # fmt: skip

    def flush(self) -> None:
        steps = self._steps
        if steps and self.writer is not None:
            columns = [_joined([step[k] for step in steps]) for k in range(len(TRAJECTORY_COLUMNS))]
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


_NO_POLICY = (math.nan, math.nan)
_NO_SIGNAL = (None, None, None)
_NO_AHEAD = (None, None)


def _floats(values: Sequence[float | None]) -> FloatArray:
    """A float array, NaN (an empty cell) for None."""
    return np.array(values, dtype=np.float64)


def _finite(values: Sequence[float]) -> FloatArray:
    """A float array, NaN (an empty cell) where a value is not finite."""
    out = _floats(values)
    out[~np.isfinite(out)] = np.nan
    return out


def _joined(parts: Sequence[Sequence[Any] | FloatArray]) -> Sequence[Any] | FloatArray:
    """One column from its steps' pieces (arrays joined as an array)."""
    if isinstance(parts[0], np.ndarray):
        return np.concatenate(parts)
    return list(itertools.chain.from_iterable(parts))


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
        vc = record.columns
        candidates = [k for k, scan in enumerate(vc.scans) if scan is not None]
        if self.vehicle_id is not None:
            candidates = [k for k in candidates if vc.id[k] == self.vehicle_id]
        else:
            index = vc.member_index
            candidates.sort(key=lambda k: (index[k] != 1, index[k], vc.id[k]))
        if not candidates:
            return
        k = candidates[0]
        vid = vc.id[k]
        if self.vehicle_id is None:
            self.vehicle_id = vid
        scan = vc.scans[k]
        if scan is None or abs(scan.stamp_s - sensed.time_s) > 1e-9:
            return  # not a new scan of this step
        pred = vc.predecessor_id[k]
        marks = _Marks(vid, sensed.index.get(vid), pred, sensed.index.get(pred or ""))
        rects = rects_seen
        if self.at_s is not None:
            self._kept = [(0, scan, rects, marks)]
            self.frozen = record.time_s >= self.at_s
            return
        if not vc.predecessor_rays[k]:
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
