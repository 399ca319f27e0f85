"""Which footprints reach into the corridor a vehicle is about to drive through."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from platoon_sumo.kernels.rectangles import rectangle_depth


@njit(cache=True)
def corridor_intrusions(
    path_xy: np.ndarray,
    path_normals: np.ndarray,
    path_starts: np.ndarray,
    members: np.ndarray,
    selves: np.ndarray,
    rects: np.ndarray,
    owners: np.ndarray,
    out_member: np.ndarray,
    out_rect: np.ndarray,
    out_gap: np.ndarray,
    out_along: np.ndarray,
) -> int:
    """Every (vehicle, rectangle) pair where the rectangle reaches into the vehicle's
    corridor, with the distance ahead where it first does. Returns how many pairs there
    were (the output arrays hold the first ones, up to their length).

    Paths are stacked: path p is `path_xy[path_starts[p]:path_starts[p + 1]]` (points
    every `spacing` metres) with its unit left normals. Vehicle j is the row
    `members[j]` = (path, front bumper's arc length, lateral offset, corridor length,
    path spacing, stride, half width, body length): its corridor is a chain of slices
    between every `stride`-th path point from the front bumper on, shifted by the
    offset, `2 * half width` wide; the gap is the distance of the first slice the
    rectangle overlaps (short by less than a slice).

    A body whose front follows a curved path cuts inside the curve: its middle lies on
    the chord between the path points half a body length before and after it (SUMO
    draws a car from its back to its front bumper, both on its lanes; a car's rear axle
    tracks inside its front). Each slice is widened towards the inside of the curve by
    the distance of its path point from that chord (the sagitta, length² / (8 radius):
    0.4 m for a 4.5 m car on a 6 m junction lane). Without it a car turning left in a
    joined junction touched, with the middle of its left side, the corner of a car
    standing beside its path (A10KW, seed 44, 193.3 s).

    Rectangles are rows (cx, cy, yaw, length, width);
    `owners[k]` is the vehicle rectangle k belongs to (a vehicle may have several), and
    `selves[j]` vehicle j's own (its rectangles are skipped; -1: none). `out_along` is
    the cosine between the rectangle's yaw and that slice's direction."""
    count = 0
    capacity = out_member.shape[0]
    n_rects = rects.shape[0]
    rc = np.cos(rects[:, 2])
    rs = np.sin(rects[:, 2])
    # rectangles by centre x: each corridor only visits those within its x range
    order = np.argsort(rects[:, 0])
    sorted_x = rects[order, 0]
    largest = 0.0
    for k in range(n_rects):
        largest = max(largest, math.hypot(0.5 * rects[k, 3], 0.5 * rects[k, 4]))
    for j in range(members.shape[0]):
        p = int(members[j, 0])
        s0, offset, length = members[j, 1], members[j, 2], members[j, 3]
        spacing, stride, hw = members[j, 4], int(members[j, 5]), members[j, 6]
        half_body = math.floor(0.5 * members[j, 7] / spacing + 0.5)
        lo, hi = path_starts[p], path_starts[p + 1]
        first = min(max(math.ceil(s0 / spacing), 0), hi - lo - 1)
        last = min(hi - lo, int((s0 + length) / spacing) + 2)
        n = (last - first + stride - 1) // stride if last > first else 0
        if n < 2:
            continue
        # the slices: centre, direction, half length; and the corridor's bounding circle
        px = np.empty(n)
        py = np.empty(n)
        for i in range(n):
            k = lo + first + i * stride
            px[i] = path_xy[k, 0] + offset * path_normals[k, 0]
            py[i] = path_xy[k, 1] + offset * path_normals[k, 1]
        m = n - 1
        sx = np.empty(m)
        sy = np.empty(m)
        sc = np.empty(m)
        ss = np.empty(m)
        sh = np.empty(m)
        sw = np.empty(m)
        mx = 0.0
        my = 0.0
        for i in range(m):
            tx = px[i + 1] - px[i]
            ty = py[i + 1] - py[i]
            norm = math.hypot(tx, ty)
            sh[i] = 0.5 * norm
            sc[i] = tx / norm if norm > 0.0 else 1.0
            ss[i] = ty / norm if norm > 0.0 else 0.0
            sx[i] = px[i] + 0.5 * tx
            sy[i] = py[i] + 0.5 * ty
            sw[i] = hw
            if half_body > 0:  # the body's chord around the slice's start (left +)
                k = lo + first + i * stride
                a, b = max(k - half_body, lo), min(k + half_body, hi - 1)
                ux, uy = path_xy[b, 0] - path_xy[a, 0], path_xy[b, 1] - path_xy[a, 1]
                chord = math.hypot(ux, uy)
                if chord > 0.0:
                    bulge = (ux * (path_xy[k, 1] - path_xy[a, 1])
                             - uy * (path_xy[k, 0] - path_xy[a, 0])) / chord  # fmt: skip
                    # the path point right of the chord (< 0): the body bulges left
                    sx[i] += 0.5 * bulge * ss[i]
                    sy[i] -= 0.5 * bulge * sc[i]
                    sw[i] += 0.5 * abs(bulge)
            mx += sx[i]
            my += sy[i]
        mx /= m
        my /= m
        reach = 0.0
        for i in range(m):
            reach = max(reach, math.hypot(sx[i] - mx, sy[i] - my) + sh[i] + sw[i])
        a = np.searchsorted(sorted_x, mx - reach - largest)
        b = np.searchsorted(sorted_x, mx + reach + largest, side="right")
        for q in range(a, b):
            k = order[q]
            if owners[k] == selves[j]:
                continue
            hl, hwk = 0.5 * rects[k, 3], 0.5 * rects[k, 4]
            size = math.hypot(hl, hwk)
            cx, cy = rects[k, 0], rects[k, 1]
            # bounding circles apart: no overlap (squared: a third of hypot's cost)
            dx = cx - mx
            dy = cy - my
            r = reach + size
            if dx * dx + dy * dy > r * r:
                continue
            for i in range(m):
                dx = cx - sx[i]
                dy = cy - sy[i]
                r = sh[i] + sw[i] + size
                if dx * dx + dy * dy > r * r:
                    continue
                depth = rectangle_depth(
                    sx[i], sy[i], sc[i], ss[i], sh[i], sw[i], cx, cy, rc[k], rs[k], hl, hwk
                )
                if depth > 0.0:
                    if count < capacity:
                        out_member[count] = j
                        out_rect[count] = k
                        out_gap[count] = max((first + i * stride) * spacing - s0, 0.0)
                        out_along[count] = rc[k] * sc[i] + rs[k] * ss[i]
                    count += 1
                    break
    return count


#: Columns of the `members` table of `corridor_intrusions`.
MEMBER_COLUMNS = (
    "path", "s_m", "offset_m", "length_m", "spacing_m", "stride", "half_width_m", "body_m",
)  # fmt: skip


def empty_outputs(capacity: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return (
        np.empty(capacity, dtype=np.int64),
        np.empty(capacity, dtype=np.int64),
        np.empty(capacity, dtype=np.float64),
        np.empty(capacity, dtype=np.float64),
    )
