"""Ray-casting kernel: the hit distance of each ray on the segments its wedge covers."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def evaluate_runs(
    out: np.ndarray,
    hits: np.ndarray,
    with_hits: bool,
    flat_first: np.ndarray,
    run_first: np.ndarray,
    counts: np.ndarray,
    num: np.ndarray,
    ex: np.ndarray,
    ey: np.ndarray,
    ids: np.ndarray,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    unset: int,
) -> None:
    """For every run (a segment and the consecutive rays its wedge covers, starting at
    ray ``run_first`` of flat row ``flat_first``) the hit distance
    ``num / (cos * ey - sin * ex)`` of each ray, kept in ``out`` where smaller (a NaN
    distance poisons the ray, as ``np.minimum`` does); with ``with_hits`` the lowest
    ``ids`` among the runs at each ray's minimum goes to ``hits``. ``unset`` is the
    identity of a ray nothing hit."""
    for r in range(counts.shape[0]):
        base = flat_first[r]
        ray0 = run_first[r]
        nu = num[r]
        e_x = ex[r]
        e_y = ey[r]
        ident = ids[r] if with_hits else unset
        for j in range(counts[r]):
            flat = base + j
            ray = ray0 + j
            denom = cos_a[ray] * e_y
            denom -= sin_a[ray] * e_x
            t = nu / denom
            old = out[flat]
            if t < old:
                out[flat] = t
                if with_hits:
                    hits[flat] = ident
            elif t == old:
                if with_hits and ident < hits[flat]:
                    hits[flat] = ident
            elif t != t and old == old:  # a NaN distance poisons the ray (its hit stays)
                out[flat] = t
