"""The compiled step fold of `RunStats` against plain numpy expressions for its running
series (count, sum of squares, largest magnitude, minimum); the whole fold is checked
against the row-by-row reference in `test_stats_equivalence.py`."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.kernels.series import FOLD_COLUMNS, FOLD_VALUES, fold_step


def numpy_add(state: np.ndarray, rows: np.ndarray, x: np.ndarray, c: int) -> None:
    ok = ~np.isnan(x)
    rows, x = rows[ok], x[ok]
    state[rows, c] += 1
    state[rows, c + 1] += x * x
    magnitude = np.where(x < 0.0, -x, x)
    state[rows, c + 2] = np.maximum(magnitude, state[rows, c + 2])
    state[rows, c + 3] = np.minimum(x, state[rows, c + 3])


value = st.one_of(st.floats(-1e6, 1e6), st.just(math.nan), st.just(-0.0))
ACCEL, JERK = 0, 4
"""The two series of vehicles without a predecessor, in an 8-column state (+ the rest)."""


@given(st.lists(st.lists(value, min_size=12, max_size=12), min_size=1, max_size=12), st.data())
@settings(max_examples=200, deadline=None)
def test_series_of_a_step_match_numpy(steps: list[list[float]], data: st.DataObject) -> None:
    """Step after step, over a random subset of rows each time (each row once a step):
    the accelerations' and jerks' series, of vehicles without a predecessor."""
    other = 8 + np.arange(len(FOLD_COLUMNS))
    columns = np.array([ACCEL if c == "accel" else JERK if c == "jerk" else int(other[k])
                        for k, c in enumerate(FOLD_COLUMNS)], dtype=np.int64)  # fmt: skip
    state = np.zeros((6, 8 + len(FOLD_COLUMNS) + 8))
    state[:, [3, 7]] = math.inf
    expected = state.copy()
    for time_s, values in enumerate(steps):
        rows = np.array(sorted(data.draw(st.sets(st.integers(0, 5), min_size=1))), dtype=np.intp)
        n = len(rows)
        accel, jerk = np.array(values[:6])[:n], np.array(values[6:])[:n]
        table = np.full((len(FOLD_VALUES), n), math.nan)
        table[FOLD_VALUES.index("accel")], table[FOLD_VALUES.index("jerk")] = accel, jerk
        no_pred = np.zeros(n, dtype=bool)
        fold_step(state, rows, float(time_s), True, no_pred, np.full(n, -1), no_pred, table,
                  columns, 1e-3)  # fmt: skip
        numpy_add(expected, rows, accel, ACCEL)
        numpy_add(expected, rows, jerk, JERK)
    np.testing.assert_array_equal(state[:, :8], expected[:, :8])
    steps_column = 8 + FOLD_COLUMNS.index("steps")
    assert state[:, steps_column].sum() == sum(state[:, 8 + FOLD_COLUMNS.index("rows")])
