"""Running per-vehicle series (count, sum of squares, largest magnitude, minimum), folded
in one compiled pass a step (``metrics.stats.RunStats``)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def add_to_series(state: np.ndarray, rows: np.ndarray, values: np.ndarray, column: int) -> None:
    """For each (row, value), value not NaN: count it in ``state[row, column]``, add its
    square to ``column + 1``, keep the largest magnitude in ``column + 2`` and the
    smallest value in ``column + 3``. Each row at most once (the step's vehicles)."""
    for k in range(rows.size):
        x = values[k]
        if x != x:
            continue
        r = rows[k]
        state[r, column] += 1.0
        state[r, column + 1] += x * x
        magnitude = -x if x < 0.0 else x
        if magnitude > state[r, column + 2]:
            state[r, column + 2] = magnitude
        if x < state[r, column + 3]:
            state[r, column + 3] = x
