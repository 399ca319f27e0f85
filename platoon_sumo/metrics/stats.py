"""Per-vehicle and per-platoon summaries, accumulated step by step in bounded memory.

`RunStats.add_step` takes one step's trajectory rows as columns (keyed by the columns of
`platoon_sumo.recorder.TRAJECTORY_COLUMNS`); the recorder feeds it online, and
`summarise_trajectories` feeds it a table, so both give the same numbers. Every
quantity is a running sum, count, minimum or maximum, kept in one per-vehicle state
table: memory grows with the number of platoon vehicles, never with the run's length.
The frequency responses, which need whole series, are computed after the run
(`platoon_sumo.metrics.string_stability`). Formulas: docs/metrics.md.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from platoon_sumo.events import Event, EventKind
from platoon_sumo.kernels.series import FOLD_COLUMNS, FOLD_VALUES, fold_step
from platoon_sumo.metrics.kernels import l2_gain
from platoon_sumo.metrics.string_stability import MIN_INPUT_SHARE, assess

Columns = Mapping[str, Sequence[Any] | np.ndarray]
"""One step's trajectory rows as columns: name -> one value per vehicle (None, NaN or ""
for a missing value)."""

#: The running series of each vehicle, and the per-vehicle state columns.
SERIES = ("spacing_error", "gap", "ttc", "time_gap", "accel", "jerk", "lateral",
          "gap_measurement_error")  # fmt: skip
_N, _SUM_SQ, _MAX_ABS, _MIN = range(4)
"""Per series: count, sum of squares, largest magnitude, smallest value."""
_PAIR = len(SERIES) * 4
#: Per-vehicle (and per-platoon, summed) V2V counts, from the vehicles' V2V inboxes.
V2V_COLUMNS = ("v2v_sent", "v2v_received", "v2v_lost")
_PAIR_FIELDS = ("n", "accel_sq", "pred_accel_sq", "speed", "speed_sq", "pred_speed",
                "pred_speed_sq")  # fmt: skip
(_ROWS, _STEPS, _FIRST_T, _LAST_T, _PREVIOUS_GAP, _SEEN, _VIEW, _IN_VIEW, _SCANS,
 _HAS_PRED, _FOLLOWING, _SATURATED, _MAX_ACCEL, _MAX_DECEL, _MAX_SPEED,
 ) = range(_PAIR + len(_PAIR_FIELDS), _PAIR + len(_PAIR_FIELDS) + 15)  # fmt: skip
_WIDTH = _MAX_SPEED + 1
_LIMITS = [_MAX_ACCEL, _MAX_DECEL, _MAX_SPEED]
_INITIAL = np.zeros(_WIDTH)
_INITIAL[[4 * k + _MIN for k in range(len(SERIES))]] = math.inf
_INITIAL[[_FIRST_T, _LAST_T, _PREVIOUS_GAP]] = math.nan
_INITIAL[_LIMITS] = math.inf  # no limit known: never at it
#: A follower's acceleration or speed within this of its vehicle's limit is at the limit.
AT_LIMIT_TOLERANCE = 1e-3


def _series(name: str) -> int:
    return 4 * SERIES.index(name)


_FOLD_KEYS = ("gap_to_predecessor_m", "accel_mps2", "speed_mps", "jerk_mps3", "desired_gap_m",
              "spacing_error_m", "ttc_s", "time_gap_s", "lateral_deviation_m",
              "measured_gap_m")  # fmt: skip
"""The trajectory column of each of `fold_step`'s values but the last (in view: `_in_view`)."""
_STATE_COLUMNS = {
    "rows": _ROWS, "first_t": _FIRST_T, "last_t": _LAST_T, "previous_gap": _PREVIOUS_GAP,
    "steps": _STEPS, "has_pred": _HAS_PRED, "following": _FOLLOWING, "saturated": _SATURATED,
    "max_accel": _MAX_ACCEL, "max_decel": _MAX_DECEL, "max_speed": _MAX_SPEED,
    "scans": _SCANS, "seen": _SEEN, "view": _VIEW, "in_view": _IN_VIEW, "pair": _PAIR,
}  # fmt: skip
_FOLD_STATE_COLUMNS = np.array(
    [_STATE_COLUMNS[c] if c in _STATE_COLUMNS else _series(c) for c in FOLD_COLUMNS],
    dtype=np.int64,
)
assert len(_FOLD_KEYS) + 1 == len(FOLD_VALUES) and FOLD_VALUES[-1] == "in_view"


def _floats(columns: Columns, key: str, n: int) -> np.ndarray:
    """A numeric column as float64, NaN where missing (None, "" or absent)."""
    values = columns.get(key)
    if values is None:
        return np.full(n, math.nan)
    try:
        return np.asarray(values, dtype=np.float64).reshape(n)
    except (TypeError, ValueError):  # text cells ("" from a CSV read as text)
        return pd.to_numeric(pd.Series(list(values), dtype=object), errors="coerce").to_numpy(
            dtype=np.float64
        )


def given(value: Any) -> bool:
    """A cell that holds a value (not None, "" or NaN)."""
    return not (value is None or value == "" or (isinstance(value, float) and value != value))


@dataclass
class VehicleStats:
    """A platoon vehicle's identity and event counts; its running series live in
    `RunStats`' state table (row `row`)."""

    vehicle_id: str
    platoon_id: str
    member_index: int
    role: str
    row: int
    emergency_brakings: int = 0
    collisions: int = 0
    collisions_at_fault: int = 0
    red_light_violations: int = 0
    cut_ins: int = 0
    v2v: tuple[int, int, int] | None = None
    """V2V messages sent, received and lost so far; None: no V2V channel."""


@dataclass
class PlatoonStats:
    platoon_id: str
    members: int
    complete_steps: int = 0
    judged_steps: int = 0
    """Complete steps on which every follower had a scan to judge its view by."""
    intact_steps: int = 0
    splits: int = 0
    window_splits: int = 0
    """Splits from the start of the metrics window (the string-stability verdict's)."""


class RunStats:
    """Feed it every step's columns; read `vehicle_summaries()` / `platoon_summaries()`.

    `planned`: members per platoon (from the scenario); platoons not in it count the
    members seen. `limits`: (max acceleration, max deceleration, max speed) of each
    platoon's vehicles, to tell when a follower drives at them (saturation); platoons
    not in it are only checked for supervisor interventions. Quality metrics use the
    rows from `start_s` on; event counts (collisions, emergency brakings, red lights,
    cut-ins) the whole run. A step is folded in by one compiled pass over its vehicles
    (`kernels.series.fold_step`, each vehicle once a step).
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
        self._state = np.tile(_INITIAL, (16, 1))

    # ------------------------------------------------------------------ feeding

    def _rows(self, ids: list[str], columns: Columns) -> np.ndarray:
        """State rows of the step's vehicles (new vehicles get one)."""
        vehicles = self.vehicles
        out = np.empty(len(ids), dtype=np.intp)
        for k, vid in enumerate(ids):
            v = vehicles.get(vid)
            if v is None:
                v = vehicles[vid] = self._new_vehicle(vid, k, columns)
            out[k] = v.row
        return out

    def _new_vehicle(self, vid: str, k: int, columns: Columns) -> VehicleStats:
        row = len(self.vehicles)
        if row == len(self._state):
            self._state = np.vstack([self._state, np.tile(_INITIAL, (row, 1))])
        index: Any = columns["member_index"][k] if "member_index" in columns else None
        role: Any = columns["role"][k] if "role" in columns else None
        platoon = str(columns["platoon_id"][k])
        if platoon in self.limits:
            self._state[row, _LIMITS] = self.limits[platoon]
        return VehicleStats(
            vid, platoon, int(index) if given(index) else 0, str(role) if given(role) else "",
            row,
        )  # fmt: skip

    def add_step(self, time_s: float, columns: Columns) -> None:
        """Fold in one step: every column one value per vehicle (each vehicle once)."""
        ids = [str(v) for v in columns["vehicle_id"]]
        n = len(ids)
        if n == 0:
            return
        if len(set(ids)) != n:
            raise ValueError(f"a vehicle has more than one row at t={time_s}")
        rows = self._rows(ids, columns)
        in_window = time_s >= self.start_s - 1e-9
        if in_window:
            pred_ids = columns.get("predecessor_id", [None] * n)
            has_pred = np.fromiter((given(p) for p in pred_ids), dtype=bool, count=n)
            in_view = _in_view(columns, n)
            at = {vid: k for k, vid in enumerate(ids)}
            pred = np.fromiter(
                (at.get(str(p), -1) if h else -1 for p, h in zip(pred_ids, has_pred, strict=True)),
                dtype=np.intp, count=n,
            )  # fmt: skip
            overridden = np.fromiter(map(given, columns.get("supervisor", [None] * n)),
                                     dtype=bool, count=n)  # fmt: skip
            values = np.stack([_floats(columns, key, n) for key in _FOLD_KEYS] + [in_view])
        else:  # before the metrics window only the gap is kept (the next step's previous)
            has_pred = overridden = np.zeros(n, dtype=bool)
            pred = np.full(n, -1, dtype=np.intp)
            values = np.full((len(FOLD_VALUES), n), math.nan)
            values[0] = _floats(columns, _FOLD_KEYS[0], n)
        fold_step(
            self._state, rows, time_s, in_window, has_pred, pred, overridden, values,
            _FOLD_STATE_COLUMNS, AT_LIMIT_TOLERANCE,
        )  # fmt: skip
        if in_window:
            self._platoon_step(columns, n, has_pred, values[-1])

    def _platoon_step(
        self, columns: Columns, n: int, has_pred: np.ndarray, in_view: np.ndarray
    ) -> None:
        groups: dict[str, list[int]] = {}
        for k, pid in enumerate(columns["platoon_id"]):
            groups.setdefault(str(pid), []).append(k)
        index = _floats(columns, "member_index", n)
        intact_row = ~has_pred | (in_view > 0.0)
        # a follower with a laser but no scan yet (its first step) is not judged; one
        # without a laser never is: its platoon has no intactness (None)
        judged_row = ~has_pred | ~np.isnan(in_view)
        judged, intact = judged_row.tolist(), intact_row.tolist()  # a few rows a platoon
        for pid, members in groups.items():
            planned = self.planned.get(pid)
            if planned is None:
                planned = int(np.nan_to_num(index[members]).max()) + 1
            p = self.platoons.get(pid)
            if p is None:
                p = self.platoons[pid] = PlatoonStats(pid, planned)
            p.members = max(p.members, len(members))
            if len(members) < p.members or len(members) < 2:
                continue
            p.complete_steps += 1
            if all(judged[k] for k in members):
                p.judged_steps += 1
                p.intact_steps += int(all(intact[k] for k in members))

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
                p.window_splits += int(e.time_s >= self.start_s - 1e-9)
            elif v is None:
                continue
            elif kind is EventKind.RED_LIGHT:
                v.red_light_violations += 1
            elif kind is EventKind.EMERGENCY_BRAKING:
                v.emergency_brakings += 1
            elif kind is EventKind.CUT_IN:
                v.cut_ins += 1

    def add_v2v(self, vehicle_id: str, sent: int, received: int, lost: int) -> None:
        """A vehicle's V2V totals so far (its inboxes' cumulative counts: the latest
        replace the earlier ones), whole run like the event counts."""
        v = self.vehicles.get(vehicle_id)
        if v is not None:
            v.v2v = (sent, received, lost)

    # ------------------------------------------------------------------ results

    def vehicle_summaries(self) -> list[dict[str, Any]]:
        ordered = sorted(self.vehicles.values(), key=lambda v: (v.platoon_id, v.member_index))
        return [self._summary(v) for v in ordered]

    def _summary(self, v: VehicleStats) -> dict[str, Any]:
        state = [float(x) for x in self._state[v.row]]

        def rms(name: str) -> float | None:
            c = _series(name)
            return math.sqrt(state[c + _SUM_SQ] / state[c + _N]) if state[c + _N] else None

        def peak(name: str) -> float | None:
            c = _series(name)
            return state[c + _MAX_ABS] if state[c + _N] else None

        def smallest(name: str) -> float | None:
            c = _series(name)
            return state[c + _MIN] if state[c + _N] else None

        seen = bool(state[_SEEN])
        view, in_view = int(state[_VIEW]), int(state[_IN_VIEW])
        share = in_view / view if seen else (0.0 if state[_SCANS] else None)
        following = state[_FOLLOWING]
        return {
            "vehicle_id": v.vehicle_id,
            "platoon_id": v.platoon_id,
            "member_index": v.member_index,
            "role": v.role,
            "steps": int(state[_STEPS]),
            "first_time_s": state[_FIRST_T],
            "last_time_s": state[_LAST_T],
            "rms_spacing_error_m": rms("spacing_error"),
            "max_abs_spacing_error_m": peak("spacing_error"),
            "min_gap_m": smallest("gap"),
            "min_ttc_s": smallest("ttc"),
            "min_time_gap_s": smallest("time_gap"),
            "rms_accel_mps2": rms("accel"),
            "max_abs_accel_mps2": peak("accel"),
            "rms_jerk_mps3": rms("jerk"),
            "max_abs_jerk_mps3": peak("jerk"),
            "rms_lateral_deviation_m": rms("lateral"),
            "max_lateral_deviation_m": peak("lateral"),
            "rms_gap_measurement_error_m": rms("gap_measurement_error"),
            "in_view_share": share,
            "lost_scans": int(state[_SCANS]) - in_view if following else None,
            "saturated_share": state[_SATURATED] / following if following else None,
            **_pair_gains(state[_PAIR : _PAIR + len(_PAIR_FIELDS)]),
            "cut_ins": v.cut_ins,
            "emergency_brakings": v.emergency_brakings,
            "collisions": v.collisions,
            "collisions_at_fault": v.collisions_at_fault,
            "red_light_violations": v.red_light_violations,
            **dict(zip(V2V_COLUMNS, v.v2v or (None, None, None), strict=True)),
        }

    def followers(self) -> dict[str, dict[str, dict[str, Any]]]:
        """{platoon: {vehicle: the `followers` entry of summary.json}} of every vehicle
        that had a predecessor."""
        out: dict[str, dict[str, dict[str, Any]]] = {}
        for v in sorted(self.vehicles.values(), key=lambda v: (v.platoon_id, v.vehicle_id)):
            if not self._state[v.row, _HAS_PRED]:
                continue
            s = self._summary(v)
            entry: dict[str, Any] = {
                "steps": int(self._state[v.row, _ROWS]),
                "in_view_share": s["in_view_share"],
                "lost_scans": s["lost_scans"],
                "min_gap_m": s["min_gap_m"],
                "rms_spacing_error_m": s["rms_spacing_error_m"],
            }
            if self._state[v.row, _series("lateral") + _N]:
                entry["max_lateral_deviation_m"] = s["max_lateral_deviation_m"]
                entry["rms_lateral_deviation_m"] = s["rms_lateral_deviation_m"]
            out.setdefault(v.platoon_id, {})[v.vehicle_id] = entry
        return out

    def platoon_summaries(
        self, vehicles: Sequence[Mapping[str, Any]] | None = None,
        methods: Mapping[str, str | None] | None = None,
    ) -> list[dict[str, Any]]:  # fmt: skip
        """One row per platoon from `vehicles` (default: `vehicle_summaries()`; rows with
        the frequency responses' fields after the run) and each platoon's frequency
        response method (`methods`)."""
        result = []
        vehicles = self.vehicle_summaries() if vehicles is None else vehicles
        for pid in sorted({v["platoon_id"] for v in vehicles}):
            members = [v for v in vehicles if v["platoon_id"] == pid]
            p = self.platoons.get(pid) or PlatoonStats(pid, self.planned.get(pid, len(members)))
            result.append(platoon_summary(p, members, (methods or {}).get(pid)))
        return result


def _pair_gains(pair: list[float]) -> dict[str, float | None]:
    """l2 gains of a follower's acceleration and speed deviations (from their mean over
    the common window) against its predecessor's, and the predecessor's speed deviation
    (the disturbance the follower received)."""
    n, accel_sq, pred_accel_sq, speed, speed_sq, pred_speed, pred_speed_sq = pair
    if not n:
        return {"accel_l2_gain": None, "speed_l2_gain": None, "predecessor_speed_std_mps": None}
    own = max(speed_sq - speed**2 / n, 0.0)
    pred = max(pred_speed_sq - pred_speed**2 / n, 0.0)
    return {
        "accel_l2_gain": l2_gain(accel_sq, pred_accel_sq),
        "speed_l2_gain": l2_gain(own, pred),
        "predecessor_speed_std_mps": math.sqrt(pred / n),
    }


def _in_view(columns: Columns, n: int) -> np.ndarray:
    """1.0 / 0.0 where the predecessor was in view (the flag, else the ray count), NaN
    where the row does not say."""
    flag = _floats(columns, "predecessor_in_view", n)
    rays = _floats(columns, "predecessor_rays", n)
    said = np.where(np.isnan(flag), rays, flag)
    return np.where(np.isnan(said), math.nan, (said > 0.0).astype(np.float64))


def _max(values: Iterable[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return max(vals) if vals else None


def _min(values: Iterable[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return min(vals) if vals else None


def _total(values: Iterable[int | None]) -> int | None:
    """The sum of the given values, None when none is."""
    vals = [v for v in values if v is not None]
    return sum(vals) if vals else None


def peak_error_ratios(members: Sequence[Mapping[str, Any]]) -> list[float | None]:
    """max|e_k| / max|e_(k-1)| for consecutive followers (by member index), k >= 2; None
    where the one ahead's peak is below `MIN_INPUT_SHARE` of the largest follower's (a
    ratio of remnants of a damped disturbance measures noise, not the control law)."""
    followers = sorted(
        (m for m in members if m.get("max_abs_spacing_error_m") is not None),
        key=lambda m: m["member_index"],
    )
    if not followers:
        return []
    floor = MIN_INPUT_SHARE * max(m["max_abs_spacing_error_m"] for m in followers)
    ratios: list[float | None] = []
    for prev, cur in itertools.pairwise(followers):
        den = prev["max_abs_spacing_error_m"]
        ratios.append(cur["max_abs_spacing_error_m"] / den if den > 0 and den >= floor else None)
    return ratios


def platoon_summary(
    p: PlatoonStats, members: Sequence[Mapping[str, Any]], method: str | None = None
) -> dict[str, Any]:
    """One platoons.csv row from the platoon's counters and its members' summaries (with
    their frequency-response fields, and the platoon's `method`, when estimated)."""
    intact_share = p.intact_steps / p.judged_steps if p.judged_steps else None
    followers = sorted((m for m in members if m.get("saturated_share") is not None),
                       key=lambda m: m["member_index"])  # fmt: skip
    leader_speed_std = followers[0].get("predecessor_speed_std_mps") if followers else None
    worst = max(
        (m for m in followers if m.get("frequency_gain") is not None),
        key=lambda m: m["frequency_gain"], default=None,
    )  # fmt: skip
    return {
        "platoon_id": p.platoon_id,
        "members": p.members,
        "vehicles_seen": len(members),
        **assess(members, p.members, p.window_splits, intact_share),
        "leader_speed_std_mps": leader_speed_std,
        "max_saturated_share": _max(m["saturated_share"] for m in followers),
        "max_accel_l2_gain": _max(m.get("accel_l2_gain") for m in members),
        "max_speed_l2_gain": _max(m.get("speed_l2_gain") for m in members),
        "frequency_response": method,
        "max_frequency_gain": worst["frequency_gain"] if worst else None,
        "max_frequency_gain_hz": worst["frequency_gain_hz"] if worst else None,
        "max_spacing_error_l2_ratio": _max(m.get("spacing_error_l2_ratio") for m in members),
        "max_spacing_error_peak_ratio": _max(peak_error_ratios(members)),
        "max_rms_spacing_error_m": _max(m["rms_spacing_error_m"] for m in members),
        "max_abs_spacing_error_m": _max(m["max_abs_spacing_error_m"] for m in members),
        "min_gap_m": _min(m["min_gap_m"] for m in members),
        "min_ttc_s": _min(m["min_ttc_s"] for m in members),
        "max_rms_accel_mps2": _max(m["rms_accel_mps2"] for m in members),
        "max_rms_jerk_mps3": _max(m["rms_jerk_mps3"] for m in members),
        "max_lateral_deviation_m": _max(m["max_lateral_deviation_m"] for m in members),
        "complete_steps": p.complete_steps,
        "intact_share": intact_share,
        "splits": p.splits,
        "cut_ins": sum(m["cut_ins"] for m in members),
        "collisions": sum(m["collisions"] for m in members),
        "collisions_at_fault": sum(m["collisions_at_fault"] for m in members),
        "emergency_brakings": sum(m["emergency_brakings"] for m in members),
        "red_light_violations": sum(m["red_light_violations"] for m in members),
        **{key: _total(m[key] for m in members) for key in V2V_COLUMNS},
    }


def table_steps(frame: pd.DataFrame) -> Iterable[tuple[float, dict[str, np.ndarray]]]:
    """(time, columns of that step) of a trajectory table, in time order."""
    frame = frame.sort_values("time_s", kind="stable")
    for time_s, group in frame.groupby("time_s", sort=True):
        yield float(np.float64(time_s)), {c: group[c].to_numpy() for c in group.columns}
