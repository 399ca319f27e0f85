"""How deep two rectangles overlap (separating axes), for the compiled kernels."""

from __future__ import annotations

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
