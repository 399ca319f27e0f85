"""The row-by-row ``RunStats`` as it was before it became columnar (commit f69acf5), kept
as the test oracle of ``platoon_sumo.metrics.stats``: its summaries from the same steps
must be the same. Do not use in package code; change it only where a metric's definition
changes (since then: `time_gap_s` renamed from `time_headway_s`; `lost_scans` counted from
the first scan; `saturated_share` and `predecessor_speed_std_mps` added; issue 13).

Per-vehicle and per-platoon summaries, accumulated step by step in bounded memory.

`RunStats.add_step` takes one step's trajectory rows (dicts keyed by the columns of
`platoon_sumo.recorder.TRAJECTORY_COLUMNS`); the recorder feeds it online, and
`summarise_trajectories` feeds it a table, so both give the same numbers. Every
quantity is a running sum, count, minimum or maximum: memory grows with the number of
platoon vehicles, never with the run's length. Formulas: docs/metrics.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from platoon_sumo.events import Event, EventKind
from platoon_sumo.metrics.kernels import l2_gain
from platoon_sumo.metrics.stats import AT_LIMIT_TOLERANCE, platoon_summary

Row = Mapping[str, Any]


def _num(row: Row, key: str) -> float | None:
    """A numeric cell, None when missing, empty or NaN."""
    value = row.get(key)
    if type(value) is float:  # the recorder's rows: no conversion needed
        return None if value != value else value
    if value is None or value == "":
        return None
    value = float(value)
    return None if math.isnan(value) else value


def _text(row: Row, key: str) -> str | None:
    value = row.get(key)
    if value is None or value == "" or (isinstance(value, float) and math.isnan(value)):
        return None
    return str(value)


@dataclass
class Running:
    """Count, sum of squares, largest magnitude and smallest value of a series."""

    n: int = 0
    sum_sq: float = 0.0
    max_abs: float = 0.0
    min: float = math.inf

    def add(self, x: float | None) -> None:
        if x is None:
            return
        self.n += 1
        self.sum_sq += x * x
        magnitude = -x if x < 0.0 else x
        if magnitude > self.max_abs:
            self.max_abs = magnitude
        if x < self.min:
            self.min = x

    def rms(self) -> float | None:
        return math.sqrt(self.sum_sq / self.n) if self.n else None

    def peak(self) -> float | None:
        return self.max_abs if self.n else None

    def smallest(self) -> float | None:
        return self.min if self.n else None


@dataclass
class PairEnergy:
    """Sums over the steps a follower and its predecessor are both in the window."""

    n: int = 0
    accel_sq: float = 0.0
    pred_accel_sq: float = 0.0
    speed: float = 0.0
    speed_sq: float = 0.0
    pred_speed: float = 0.0
    pred_speed_sq: float = 0.0

    def add(self, accel: float, pred_accel: float, speed: float, pred_speed: float) -> None:
        self.n += 1
        self.accel_sq += accel * accel
        self.pred_accel_sq += pred_accel * pred_accel
        self.speed += speed
        self.speed_sq += speed * speed
        self.pred_speed += pred_speed
        self.pred_speed_sq += pred_speed * pred_speed

    def accel_gain(self) -> float | None:
        return l2_gain(self.accel_sq, self.pred_accel_sq) if self.n else None

    def speed_gain(self) -> float | None:
        """l2 gain of the speed deviations from their mean over the common window."""
        if not self.n:
            return None
        own = max(self.speed_sq - self.speed**2 / self.n, 0.0)
        pred = max(self.pred_speed_sq - self.pred_speed**2 / self.n, 0.0)
        return l2_gain(own, pred)

    def pred_speed_std(self) -> float | None:
        if not self.n:
            return None
        return math.sqrt(max(self.pred_speed_sq - self.pred_speed**2 / self.n, 0.0) / self.n)


@dataclass
class VehicleStats:
    vehicle_id: str
    platoon_id: str
    member_index: int
    role: str
    rows: int = 0
    steps: int = 0
    first_time_s: float = math.nan
    last_time_s: float = math.nan
    spacing_error: Running = field(default_factory=Running)
    gap: Running = field(default_factory=Running)
    ttc: Running = field(default_factory=Running)
    time_gap: Running = field(default_factory=Running)
    accel: Running = field(default_factory=Running)
    jerk: Running = field(default_factory=Running)
    lateral: Running = field(default_factory=Running)
    gap_measurement_error: Running = field(default_factory=Running)
    pair: PairEnergy = field(default_factory=PairEnergy)
    seen: bool = False
    view_steps: int = 0
    in_view_steps: int = 0
    scans: int = 0
    following_steps: int = 0
    saturated_steps: int = 0
    limits: tuple[float, float, float] = (math.inf, math.inf, math.inf)
    has_predecessor: bool = False
    emergency_brakings: int = 0
    collisions: int = 0
    collisions_at_fault: int = 0
    red_light_violations: int = 0
    cut_ins: int = 0
    _previous_gap: float | None = None

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "vehicle_id": self.vehicle_id,
            "platoon_id": self.platoon_id,
            "member_index": self.member_index,
            "role": self.role,
            "steps": self.steps,
            "first_time_s": self.first_time_s,
            "last_time_s": self.last_time_s,
            "rms_spacing_error_m": self.spacing_error.rms(),
            "max_abs_spacing_error_m": self.spacing_error.peak(),
            "min_gap_m": self.gap.smallest(),
            "min_ttc_s": self.ttc.smallest(),
            "min_time_gap_s": self.time_gap.smallest(),
            "rms_accel_mps2": self.accel.rms(),
            "max_abs_accel_mps2": self.accel.peak(),
            "rms_jerk_mps3": self.jerk.rms(),
            "max_abs_jerk_mps3": self.jerk.peak(),
            "rms_lateral_deviation_m": self.lateral.rms(),
            "max_lateral_deviation_m": self.lateral.peak(),
            "rms_gap_measurement_error_m": self.gap_measurement_error.rms(),
            "in_view_share": self.in_view_share(),
            "lost_scans": self.scans - self.in_view_steps if self.following_steps else None,
            "saturated_share": self.saturated_steps / self.following_steps
            if self.following_steps
            else None,
            "accel_l2_gain": self.pair.accel_gain(),
            "speed_l2_gain": self.pair.speed_gain(),
            "predecessor_speed_std_mps": self.pair.pred_speed_std(),
            "cut_ins": self.cut_ins,
            "emergency_brakings": self.emergency_brakings,
            "collisions": self.collisions,
            "collisions_at_fault": self.collisions_at_fault,
            "red_light_violations": self.red_light_violations,
            "v2v_sent": None,  # V2V counts come from inboxes, never from the table
            "v2v_received": None,
            "v2v_lost": None,
        }
        return out

    def in_view_share(self) -> float | None:
        if self.seen:
            return self.in_view_steps / self.view_steps
        return 0.0 if self.scans else None

    def follower_summary(self) -> dict[str, Any]:
        """The `followers` entry of summary.json (kept from earlier versions)."""
        s = self.summary()
        out: dict[str, Any] = {
            "steps": self.rows,
            "in_view_share": s["in_view_share"],
            "lost_scans": s["lost_scans"],
            "min_gap_m": s["min_gap_m"],
            "rms_spacing_error_m": s["rms_spacing_error_m"],
        }
        if self.lateral.n:
            out["max_lateral_deviation_m"] = s["max_lateral_deviation_m"]
            out["rms_lateral_deviation_m"] = s["rms_lateral_deviation_m"]
        return out


@dataclass
class PlatoonStats:
    platoon_id: str
    members: int
    complete_steps: int = 0
    judged_steps: int = 0
    intact_steps: int = 0
    splits: int = 0
    window_splits: int = 0


class RunStats:
    """Feed it every step's rows; read `vehicle_summaries()` / `platoon_summaries()`.

    `planned`: members per platoon (from the scenario); platoons not in it count the
    members seen. Quality metrics use the rows from `start_s` on; event counts
    (collisions, emergency brakings, red lights, cut-ins) the whole run.
    """

    def __init__(
        self, planned: Mapping[str, int] | None = None, start_s: float = 0.0,
        limits: Mapping[str, tuple[float, float, float]] | None = None,
    ):  # fmt: skip
        self.planned = dict(planned or {})
        self.start_s = start_s
        self.limits = dict(limits or {})
        self.vehicles: dict[str, VehicleStats] = {}
        self.platoons: dict[str, PlatoonStats] = {}

    # ------------------------------------------------------------------ feeding

    def _vehicle(self, row: Row) -> VehicleStats:
        vid = str(row["vehicle_id"])
        stats = self.vehicles.get(vid)
        if stats is None:
            stats = self.vehicles[vid] = VehicleStats(
                vid, str(row["platoon_id"]), int(row.get("member_index") or 0),
                str(row.get("role") or ""),
                limits=self.limits.get(str(row["platoon_id"]), (math.inf,) * 3),
            )  # fmt: skip
        return stats

    def add_step(self, time_s: float, rows: Iterable[Row]) -> None:
        rows = list(rows)
        by_id = {str(r["vehicle_id"]): r for r in rows}
        in_window = time_s >= self.start_s - 1e-9
        for row in rows:
            v = self._vehicle(row)
            v.rows += 1
            if math.isnan(v.first_time_s):
                v.first_time_s = time_s
            v.last_time_s = time_s
            pred_id = _text(row, "predecessor_id")
            gap = _num(row, "gap_to_predecessor_m")
            previous_gap, v._previous_gap = v._previous_gap, gap
            if not in_window:
                continue
            v.steps += 1
            accel = _num(row, "accel_mps2")
            v.accel.add(accel)
            v.jerk.add(_num(row, "jerk_mps3"))
            if pred_id is None:
                continue
            v.has_predecessor = True
            desired = _num(row, "desired_gap_m")
            error = _num(row, "spacing_error_m")
            if error is None and gap is not None and desired is not None:
                error = gap - desired
            v.spacing_error.add(error)
            v.gap.add(gap)
            v.ttc.add(_num(row, "ttc_s"))
            v.time_gap.add(_num(row, "time_gap_s"))
            v.lateral.add(_num(row, "lateral_deviation_m"))
            measured = _num(row, "measured_gap_m")
            if measured is not None and previous_gap is not None:
                v.gap_measurement_error.add(measured - previous_gap)
            v.following_steps += 1
            max_accel, max_decel, max_speed = v.limits
            speed = _num(row, "speed_mps")
            v.saturated_steps += int(
                _text(row, "supervisor") is not None
                or (accel is not None and accel >= max_accel - AT_LIMIT_TOLERANCE)
                or (accel is not None and accel <= AT_LIMIT_TOLERANCE - max_decel)
                or (speed is not None and speed >= max_speed - AT_LIMIT_TOLERANCE)
            )
            in_view = _in_view(row)
            if in_view is not None:
                v.scans += 1
                v.seen = v.seen or in_view
                if v.seen:
                    v.view_steps += 1
                    v.in_view_steps += int(in_view)
            pred = by_id.get(pred_id)
            if pred is not None and accel is not None and speed is not None:
                pa, ps = _num(pred, "accel_mps2"), _num(pred, "speed_mps")
                if pa is not None and ps is not None:
                    v.pair.add(accel, pa, speed, ps)
        if in_window:
            self._platoon_step(rows)

    def _platoon_step(self, rows: list[Row]) -> None:
        groups: dict[str, list[Row]] = {}
        for row in rows:
            groups.setdefault(str(row["platoon_id"]), []).append(row)
        for pid, members in groups.items():
            planned = self.planned.get(pid)
            if planned is None:
                planned = max(int(r.get("member_index") or 0) for r in members) + 1
            p = self.platoons.get(pid)
            if p is None:
                p = self.platoons[pid] = PlatoonStats(pid, planned)
            p.members = max(p.members, len(members))
            if len(members) < p.members or len(members) < 2:
                continue
            p.complete_steps += 1
            views = [_in_view(r) for r in members if _text(r, "predecessor_id") is not None]
            if None not in views:  # every follower has a scan to judge by
                p.judged_steps += 1
                p.intact_steps += int(all(views))

    def add_events(self, events: Iterable[Event]) -> None:
        """Count a step's events per vehicle and platoon (the one source of every event
        count; definitions in docs/metrics.md)."""
        for e in events:
            kind = e.kind
            if kind in (EventKind.COLLISION, EventKind.WALL_CONTACT):
                for vid in (e.vehicle_id, e.other_id):
                    if vid in self.vehicles:
                        self.vehicles[vid].collisions += 1
                if e.at_fault in self.vehicles:
                    self.vehicles[e.at_fault].collisions_at_fault += 1
                continue
            v = self.vehicles.get(e.vehicle_id)
            if kind is EventKind.SPLIT:
                p = self.platoons.get(e.platoon_id)
                if p is None:
                    p = self.platoons[e.platoon_id] = PlatoonStats(
                        e.platoon_id, self.planned.get(e.platoon_id, 0)
                    )
                p.splits += 1
                if e.time_s >= self.start_s - 1e-9:
                    p.window_splits += 1
            elif v is None:
                continue
            elif kind is EventKind.RED_LIGHT:
                v.red_light_violations += 1
            elif kind is EventKind.EMERGENCY_BRAKING:
                v.emergency_brakings += 1
            elif kind is EventKind.CUT_IN:
                v.cut_ins += 1

    # ------------------------------------------------------------------ results

    def vehicle_summaries(self) -> list[dict[str, Any]]:
        ordered = sorted(self.vehicles.values(), key=lambda v: (v.platoon_id, v.member_index))
        return [v.summary() for v in ordered]

    def followers(self) -> dict[str, dict[str, dict[str, Any]]]:
        out: dict[str, dict[str, dict[str, Any]]] = {}
        for v in sorted(self.vehicles.values(), key=lambda v: (v.platoon_id, v.vehicle_id)):
            if v.has_predecessor or _was_follower(v):
                out.setdefault(v.platoon_id, {})[v.vehicle_id] = v.follower_summary()
        return out

    def platoon_summaries(self) -> list[dict[str, Any]]:
        result = []
        vehicles = self.vehicle_summaries()
        for pid in sorted({v["platoon_id"] for v in vehicles}):
            members = [v for v in vehicles if v["platoon_id"] == pid]
            p = self.platoons.get(pid) or PlatoonStats(pid, self.planned.get(pid, len(members)))
            result.append(platoon_summary(p, members))
        return result


def _was_follower(v: VehicleStats) -> bool:
    return v.rows > 0 and v.role == "follower" and v.has_predecessor


def _in_view(row: Row) -> bool | None:
    flag = _num(row, "predecessor_in_view")
    if flag is not None:
        return flag > 0
    rays = _num(row, "predecessor_rays")
    return None if rays is None else rays > 0
