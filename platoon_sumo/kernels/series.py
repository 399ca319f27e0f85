"""One step of trajectory rows folded into ``metrics.stats.RunStats``' per-vehicle state
table in one compiled pass: the running series (count, sum of squares, largest magnitude,
minimum), the step and time counters, saturation, the predecessor-in-view counts and the
follower-predecessor pair sums."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _add_one(state: np.ndarray, r: int, column: int, x: float) -> None:
    """Count ``x`` (not NaN) in ``state[r, column]``, add its square to ``column + 1``,
    keep the largest magnitude in ``column + 2`` and the smallest value in ``column + 3``."""
    if x != x:
        return
    state[r, column] += 1.0
    state[r, column + 1] += x * x
    magnitude = -x if x < 0.0 else x
    if magnitude > state[r, column + 2]:
        state[r, column + 2] = magnitude
    if x < state[r, column + 3]:
        state[r, column + 3] = x


#: The entries of ``fold_step``'s ``values``, one row each.
FOLD_VALUES = ("gap", "accel", "speed", "jerk", "desired_gap", "spacing_error", "ttc",
               "time_gap", "lateral", "measured_gap", "in_view")  # fmt: skip
#: The state table's columns ``fold_step`` writes, in the order of its ``columns``.
FOLD_COLUMNS = ("rows", "first_t", "last_t", "previous_gap", "steps", "accel", "jerk",
                "spacing_error", "gap", "ttc", "time_gap", "lateral", "gap_measurement_error",
                "has_pred", "following", "saturated", "max_accel", "max_decel", "max_speed",
                "scans", "seen", "view", "in_view", "pair")  # fmt: skip


@njit(cache=True)
def fold_step(
    state: np.ndarray,
    rows: np.ndarray,
    time_s: float,
    in_window: bool,
    has_pred: np.ndarray,
    pred: np.ndarray,
    overridden: np.ndarray,
    values: np.ndarray,
    columns: np.ndarray,
    tolerance: float,
) -> None:
    """One step's vehicles (``rows`` of ``state``, each at most once) folded into
    ``RunStats``' state table: ``values`` rows as ``FOLD_VALUES`` (NaN: no value; in
    view 1/0), the table's columns as ``FOLD_COLUMNS`` (series: their first column;
    "pair": the first of the seven pair sums). ``pred[k]``: the index in this step of
    vehicle k's predecessor, -1 if it is not in the step; ``in_window``: the step is in
    the metrics window (otherwise only the rows, times and previous gaps are kept).
    Each state cell gets the same operations, in the same order, as in the numpy
    expressions this pass replaced; ``tests/metrics/test_stats_equivalence.py`` checks
    the summaries against a row-by-row reference."""
    (c_rows, c_first, c_last, c_previous, c_steps, c_accel, c_jerk, c_error, c_gap, c_ttc,
     c_time_gap, c_lateral, c_measure, c_has, c_following, c_saturated, c_max_accel,
     c_max_decel, c_max_speed, c_scans, c_seen, c_view, c_in_view, c_pair) = columns  # fmt: skip
    for k in range(rows.size):
        r = rows[k]
        gap, accel, speed = values[0, k], values[1, k], values[2, k]
        state[r, c_rows] += 1.0
        if state[r, c_first] != state[r, c_first]:
            state[r, c_first] = time_s
        state[r, c_last] = time_s
        previous_gap = state[r, c_previous]
        state[r, c_previous] = gap
        if not in_window:
            continue
        state[r, c_steps] += 1.0
        _add_one(state, r, c_accel, accel)
        _add_one(state, r, c_jerk, values[3, k])
        if not has_pred[k]:
            continue
        state[r, c_has] = 1.0
        error = values[5, k]
        if error != error:
            error = gap - values[4, k]
        _add_one(state, r, c_error, error)
        _add_one(state, r, c_gap, gap)
        _add_one(state, r, c_ttc, values[6, k])
        _add_one(state, r, c_time_gap, values[7, k])
        _add_one(state, r, c_lateral, values[8, k])
        _add_one(state, r, c_measure, values[9, k] - previous_gap)
        state[r, c_following] += 1.0
        at_limit = (
            accel >= state[r, c_max_accel] - tolerance
            or accel <= tolerance - state[r, c_max_decel]
            or speed >= state[r, c_max_speed] - tolerance
        )
        state[r, c_saturated] += 1.0 if overridden[k] or at_limit else 0.0
        view = values[10, k]
        if view == view:
            state[r, c_scans] += 1.0
            seen = state[r, c_seen] > 0.0 or view > 0.0
            state[r, c_seen] = 1.0 if seen else 0.0
            if seen:
                state[r, c_view] += 1.0
                state[r, c_in_view] += 1.0 if view > 0.0 else 0.0
        p = pred[k]
        if p < 0:
            continue
        pa, ps = values[1, p], values[2, p]
        if accel != accel or speed != speed or pa != pa or ps != ps:
            continue
        state[r, c_pair] += 1.0
        state[r, c_pair + 1] += accel * accel
        state[r, c_pair + 2] += pa * pa
        state[r, c_pair + 3] += speed
        state[r, c_pair + 4] += speed * speed
        state[r, c_pair + 5] += ps
        state[r, c_pair + 6] += ps * ps
