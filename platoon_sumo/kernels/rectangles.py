"""How deep two rectangles overlap (separating axes), for the compiled kernels."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def rectangle_depth(
    ax: float, ay: float, ca: float, sa: float, ahl: float, ahw: float,
    bx: float, by: float, cb: float, sb: float, bhl: float, bhw: float,
) -> float:  # fmt: skip
    """Penetration depth of two rectangles (centre, cos and sin of yaw, half length,
    half width): the smallest overlap of their projections on the four edge normals,
    > 0 exactly when they overlap (the push that separates them), otherwise <= 0."""
    dx = bx - ax
    dy = by - ay
    c11 = abs(ca * cb + sa * sb)
    c12 = abs(-ca * sb + sa * cb)
    c21 = abs(-sa * cb + ca * sb)
    c22 = abs(sa * sb + ca * cb)
    return min(
        ahl + bhl * c11 + bhw * c12 - abs(dx * ca + dy * sa),
        ahw + bhl * c21 + bhw * c22 - abs(-dx * sa + dy * ca),
        bhl + ahl * c11 + ahw * c21 - abs(dx * cb + dy * sb),
        bhw + ahl * c12 + ahw * c22 - abs(-dx * sb + dy * cb),
    )


@njit(cache=True)
def overlapping_pairs_kernel(
    rects: np.ndarray, subjects: np.ndarray, tolerance_m: float
) -> np.ndarray:
    """``geometry.overlapping_pairs`` for finite (N, 5) rectangles and sorted, unique
    subject rows, in one compiled pass: (K, 2) pairs ``(i, j)``, i < j, sorted.

    A sweep instead of the oracle's grid, along the axis (x or y) the centres spread
    over most (a road along y would put every car in one x band): the rectangles sorted
    by that coordinate, each subject tests those within its bounding radius plus the
    largest one along it, by bounding circles first (the same ``hypot`` test as the
    oracle), then by penetration depth (``rectangle_depth``, the oracle's expression)."""
    n = rects.shape[0]
    radius = np.empty(n)
    for k in range(n):
        radius[k] = 0.5 * math.hypot(rects[k, 3], rects[k, 4])
    axis = 0
    if n and np.ptp(rects[:, 1]) > np.ptp(rects[:, 0]):
        axis = 1
    order = np.argsort(rects[:, axis], kind="mergesort")
    xs = rects[order, axis]
    is_subject = np.zeros(n, dtype=np.bool_)
    for s in subjects:
        is_subject[s] = True
    r_max = radius.max() if n else 0.0
    codes = np.empty(16, dtype=np.int64)
    count = 0
    for s in subjects:
        reach = radius[s] + r_max
        lo = np.searchsorted(xs, rects[s, axis] - reach, side="left")
        hi = np.searchsorted(xs, rects[s, axis] + reach, side="right")
        for q in range(lo, hi):
            k = order[q]
            if k == s or (is_subject[k] and k < s):  # a pair of subjects: found once
                continue
            i, j = (s, k) if s < k else (k, s)
            if (
                math.hypot(rects[j, 0] - rects[i, 0], rects[j, 1] - rects[i, 1])
                > radius[i] + radius[j]
            ):
                continue
            depth = rectangle_depth(
                rects[i, 0], rects[i, 1], math.cos(rects[i, 2]), math.sin(rects[i, 2]),
                0.5 * rects[i, 3], 0.5 * rects[i, 4],
                rects[j, 0], rects[j, 1], math.cos(rects[j, 2]), math.sin(rects[j, 2]),
                0.5 * rects[j, 3], 0.5 * rects[j, 4],
            )  # fmt: skip
            if depth > tolerance_m:
                if count == codes.size:
                    codes = np.concatenate((codes, np.empty(codes.size, dtype=np.int64)))
                codes[count] = i * n + j
                count += 1
    found = np.sort(codes[:count])
    pairs = np.empty((count, 2), dtype=np.int64)
    for c in range(count):
        pairs[c, 0] = found[c] // n
        pairs[c, 1] = found[c] % n
    return pairs
