"""The compiled running-series update against the plain numpy expressions it replaced."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.kernels.series import add_to_series


def numpy_add(state: np.ndarray, rows: np.ndarray, x: np.ndarray, c: int) -> None:
    ok = ~np.isnan(x)
    rows, x = rows[ok], x[ok]
    state[rows, c] += 1
    state[rows, c + 1] += x * x
    magnitude = np.where(x < 0.0, -x, x)
    state[rows, c + 2] = np.maximum(magnitude, state[rows, c + 2])
    state[rows, c + 3] = np.minimum(x, state[rows, c + 3])


value = st.one_of(st.floats(-1e6, 1e6), st.just(math.nan), st.just(-0.0))


@given(st.lists(st.lists(value, min_size=6, max_size=6), min_size=1, max_size=12), st.data())
@settings(max_examples=200, deadline=None)
def test_series_update_matches_numpy(steps: list[list[float]], data: st.DataObject) -> None:
    """Step after step, over a random subset of rows each time (each row once a step)."""
    state = np.tile([0.0, 0.0, 0.0, math.inf] * 2, (6, 1))
    expected = state.copy()
    for values in steps:
        rows = np.array(sorted(data.draw(st.sets(st.integers(0, 5), min_size=1))), dtype=np.intp)
        x = np.array(values, dtype=np.float64)[: len(rows)]
        column = data.draw(st.sampled_from([0, 4]))
        add_to_series(state, rows, x, column)
        numpy_add(expected, rows, x, column)
    np.testing.assert_array_equal(state, expected)
