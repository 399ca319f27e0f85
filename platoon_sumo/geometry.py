"""Planar geometry kernels: angle conventions, vehicle footprints, overlap tests.

Pure numpy, no SUMO import, vectorised over all vehicles so one call per step serves the
whole world. Conventions used everywhere in the package:

* yaw: radians, counter-clockwise from east (+x), wrapped to [-pi, pi);
* SUMO angle: degrees, 0 = north, clockwise (what ``vehicle.moveToXY`` expects);
* a vehicle's SUMO position is its FRONT BUMPER centre;
* a rectangle is a row ``(centre_x_m, centre_y_m, yaw_rad, length_m, width_m)`` with the
  length along yaw; the laser scanner consumes the same (N, 5) layout.
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

TWO_PI = 2.0 * math.pi

# Columns of an (N, 5) rectangle array.
CX, CY, YAW, LENGTH, WIDTH = range(5)


@overload
def wrap_angle(a: float) -> float: ...
@overload
def wrap_angle(a: ArrayLike) -> FloatArray: ...
def wrap_angle(a: ArrayLike) -> float | FloatArray:
    """Angle(s) in radians wrapped to [-pi, pi); a scalar in gives a float out."""
    arr = np.asarray(a, dtype=np.float64)
    wrapped = np.mod(arr + math.pi, TWO_PI) - math.pi
    # np.mod can round up to exactly 2*pi for tiny negative inputs; keep the interval half-open.
    wrapped = np.where(wrapped >= math.pi, wrapped - TWO_PI, wrapped)
    # Values already in range pass through untouched: (a + pi) - pi would round small angles.
    wrapped = np.where((arr >= -math.pi) & (arr < math.pi), arr, wrapped)
    return float(wrapped) if wrapped.ndim == 0 else wrapped


@overload
def yaw_to_sumo_angle_deg(yaw_rad: float) -> float: ...
@overload
def yaw_to_sumo_angle_deg(yaw_rad: ArrayLike) -> FloatArray: ...
def yaw_to_sumo_angle_deg(yaw_rad: ArrayLike) -> float | FloatArray:
    """Math yaw (rad, CCW from east) -> SUMO angle (deg, clockwise from north) in [0, 360)."""
    angle = np.mod(90.0 - np.degrees(np.asarray(yaw_rad, dtype=np.float64)), 360.0)
    angle = np.where(angle >= 360.0, 0.0, angle)
    return float(angle) if angle.ndim == 0 else angle


@overload
def sumo_angle_deg_to_yaw(angle_deg: float) -> float: ...
@overload
def sumo_angle_deg_to_yaw(angle_deg: ArrayLike) -> FloatArray: ...
def sumo_angle_deg_to_yaw(angle_deg: ArrayLike) -> float | FloatArray:
    """SUMO angle (deg, clockwise from north) -> math yaw (rad) wrapped to [-pi, pi)."""
    return wrap_angle(np.radians(90.0 - np.asarray(angle_deg, dtype=np.float64)))


def front_bumper_to_centre(
    x_m: ArrayLike, y_m: ArrayLike, yaw_rad: ArrayLike, length_m: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Footprint centre from SUMO's front-bumper position (half a length back along yaw)."""
    x, y, yaw, length = _floats(x_m, y_m, yaw_rad, length_m)
    half = 0.5 * length
    return x - half * np.cos(yaw), y - half * np.sin(yaw)


def centre_to_front_bumper(
    x_m: ArrayLike, y_m: ArrayLike, yaw_rad: ArrayLike, length_m: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Front-bumper position (what moveToXY takes) from the footprint centre."""
    x, y, yaw, length = _floats(x_m, y_m, yaw_rad, length_m)
    half = 0.5 * length
    return x + half * np.cos(yaw), y + half * np.sin(yaw)


def footprints_from_front_bumper(
    x_m: ArrayLike,
    y_m: ArrayLike,
    yaw_rad: ArrayLike,
    length_m: ArrayLike,
    width_m: ArrayLike,
) -> FloatArray:
    """(N, 5) rectangles ``(cx, cy, yaw, length, width)`` from SUMO's bumper-based poses.

    Inputs broadcast against each other (e.g. one length for every vehicle).
    """
    x, y, yaw, length, width = np.broadcast_arrays(*_floats(x_m, y_m, yaw_rad, length_m, width_m))
    cx, cy = front_bumper_to_centre(x, y, yaw, length)
    rects = np.column_stack([np.ravel(v) for v in (cx, cy, yaw, length, width)])
    return rects.astype(np.float64, copy=False)


def rectangle_corners(rects: ArrayLike) -> FloatArray:
    """(N, 4, 2) corners of (N, 5) rectangles, counter-clockwise from the front-right one."""
    r = as_rectangles(rects)
    cos, sin = np.cos(r[:, YAW]), np.sin(r[:, YAW])
    hl, hw = 0.5 * r[:, LENGTH], 0.5 * r[:, WIDTH]
    # Local corners (front-right, front-left, rear-left, rear-right): CCW for positive sizes.
    local_x = np.array([1.0, 1.0, -1.0, -1.0])[None, :] * hl[:, None]
    local_y = np.array([-1.0, 1.0, 1.0, -1.0])[None, :] * hw[:, None]
    corners = np.empty((r.shape[0], 4, 2), dtype=np.float64)
    corners[:, :, 0] = r[:, CX, None] + cos[:, None] * local_x - sin[:, None] * local_y
    corners[:, :, 1] = r[:, CY, None] + sin[:, None] * local_x + cos[:, None] * local_y
    return corners


def penetration_depths(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Pairwise separating-axis depth of rectangles ``a[k]`` and ``b[k]`` (rows broadcast).

    For convex polygons the smallest translation that separates two overlapping shapes lies
    along one of their edge normals, so the minimum projected overlap over the four axes is
    exactly the penetration depth (> 0 when interiors overlap). A value <= 0 means separated
    (or touching); its magnitude is then only a lower bound on the gap.
    """
    ra, rb = np.broadcast_arrays(as_rectangles(a), as_rectangles(b))
    dx = rb[:, CX] - ra[:, CX]
    dy = rb[:, CY] - ra[:, CY]
    ca, sa = np.cos(ra[:, YAW]), np.sin(ra[:, YAW])
    cb, sb = np.cos(rb[:, YAW]), np.sin(rb[:, YAW])
    hla, hwa = 0.5 * ra[:, LENGTH], 0.5 * ra[:, WIDTH]
    hlb, hwb = 0.5 * rb[:, LENGTH], 0.5 * rb[:, WIDTH]
    # Cosines between the axes of a (u1, u2) and of b (v1, v2).
    c11 = np.abs(ca * cb + sa * sb)  # u1 . v1
    c12 = np.abs(-ca * sb + sa * cb)  # u1 . v2
    c21 = np.abs(-sa * cb + ca * sb)  # u2 . v1
    c22 = np.abs(sa * sb + ca * cb)  # u2 . v2
    overlaps = np.stack(
        [
            hla + hlb * c11 + hwb * c12 - np.abs(dx * ca + dy * sa),  # axis u1
            hwa + hlb * c21 + hwb * c22 - np.abs(-dx * sa + dy * ca),  # axis u2
            hlb + hla * c11 + hwa * c21 - np.abs(dx * cb + dy * sb),  # axis v1
            hwb + hla * c12 + hwa * c22 - np.abs(-dx * sb + dy * cb),  # axis v2
        ]
    )
    return np.asarray(overlaps.min(axis=0), dtype=np.float64)


def rectangles_overlap(a: ArrayLike, b: ArrayLike, tolerance_m: float = 0.0) -> NDArray[np.bool_]:
    """True where rectangle ``a[k]`` and ``b[k]`` overlap by more than ``tolerance_m``.

    "By more than" means the penetration depth (the shortest push that separates them)
    exceeds the tolerance, so touching edges never count as a collision and a tolerance
    absorbs the few centimetres of slack SUMO's own footprints carry.
    """
    if not tolerance_m >= 0.0:
        raise ValueError(f"tolerance_m must be >= 0, got {tolerance_m}")
    return penetration_depths(a, b) > tolerance_m


def overlapping_pairs(rects: ArrayLike, subjects: ArrayLike, tolerance_m: float = 0.0) -> IntArray:
    """(K, 2) sorted pairs ``(i, j)``, i < j, that overlap and involve at least one subject.

    ``subjects`` is a boolean mask (N,) or an index array. Typical use: the platoon vehicles
    (subjects) against everything SUMO moves, where human-human overlaps are SUMO's business.

    Candidates come from a uniform grid whose cell is at least the largest bounding-circle
    diameter, so any overlapping pair sits in neighbouring cells: cost is O(N log N +
    candidates) with no N x N matrix, whatever the road's direction. Bounding circles then
    prune the candidates and the exact separating-axis test decides.
    """
    if not tolerance_m >= 0.0:
        raise ValueError(f"tolerance_m must be >= 0, got {tolerance_m}")
    r = as_rectangles(rects)
    n = r.shape[0]
    subject_idx = _subject_indices(subjects, n)
    empty = np.empty((0, 2), dtype=np.int64)
    if n == 0 or subject_idx.size == 0:
        return empty
    if not np.all(np.isfinite(r)):
        raise ValueError("rectangles must be finite")

    radius = 0.5 * np.hypot(r[:, LENGTH], r[:, WIDTH])
    cx, cy = r[:, CX], r[:, CY]
    span = max(float(np.ptp(cx)), float(np.ptp(cy)))
    # Any cell >= the largest diameter is correct; the lower bounds keep cell keys in int64.
    cell_m = max(2.0 * float(radius.max()), span / 2.0**30, 1e-9)
    ix = np.floor((cx - cx.min()) / cell_m).astype(np.int64) + 1
    iy = np.floor((cy - cy.min()) / cell_m).astype(np.int64) + 1
    ny = int(iy.max()) + 2  # room for the +1 neighbour row
    keys = ix * ny + iy
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]

    # Look up the 3 x 3 neighbourhood of every subject's cell.
    offsets = np.array([dx * ny + dy for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.int64)
    query = (keys[subject_idx][:, None] + offsets[None, :]).ravel()
    owner = np.repeat(subject_idx, offsets.size)
    starts = np.searchsorted(sorted_keys, query, side="left")
    counts = np.searchsorted(sorted_keys, query, side="right") - starts
    total = int(counts.sum())
    if total == 0:
        return empty
    first = np.cumsum(counts) - counts
    within = np.arange(total, dtype=np.int64) - np.repeat(first, counts)
    other = order[np.repeat(starts, counts) + within]
    subject = np.repeat(owner, counts)

    keep = other != subject
    i = np.minimum(subject[keep], other[keep])
    j = np.maximum(subject[keep], other[keep])
    # Two subjects find each other twice; the flat code dedupes and sorts in one go.
    codes = np.unique(i * n + j)
    i, j = codes // n, codes % n

    close = np.hypot(cx[j] - cx[i], cy[j] - cy[i]) <= radius[i] + radius[j]
    i, j = i[close], j[close]
    hit = rectangles_overlap(r[i], r[j], tolerance_m)
    return np.column_stack([i[hit], j[hit]]).astype(np.int64, copy=False)


def as_rectangles(rects: ArrayLike) -> FloatArray:
    """Validate and view ``rects`` as an (N, 5) float64 array (a single row is accepted)."""
    r = np.asarray(rects, dtype=np.float64)
    if r.ndim == 1 and r.shape[0] == 5:
        r = r[None, :]
    if r.ndim != 2 or r.shape[1] != 5:
        raise ValueError(
            f"rectangles must have shape (N, 5) = (cx, cy, yaw, length, width), got {r.shape}"
        )
    return r


def _subject_indices(subjects: ArrayLike, n: int) -> IntArray:
    s = np.asarray(subjects)
    if s.dtype == np.bool_:
        if s.shape != (n,):
            raise ValueError(f"subject mask must have shape ({n},), got {s.shape}")
        return np.flatnonzero(s).astype(np.int64)
    idx = np.asarray(s, dtype=np.int64).ravel()
    if idx.size and (idx.min() < 0 or idx.max() >= n):
        raise ValueError(f"subject indices must be in [0, {n}), got {idx.min()}..{idx.max()}")
    return np.unique(idx)


def _floats(*values: ArrayLike) -> tuple[FloatArray, ...]:
    return tuple(np.asarray(v, dtype=np.float64) for v in values)


def rectangles_crossing_segments(rects: ArrayLike, segments: ArrayLike) -> IntArray:
    """(K, 2) pairs (rectangle index, segment index) where a segment enters a rectangle's
    interior (touching its outline is not a crossing).

    Each segment is clipped against each nearby rectangle in the rectangle's own frame
    (Liang-Barsky); pairs are first culled by bounding boxes, so long lists of walls
    and kerbs cost little.
    """
    r = as_rectangles(rects)
    seg = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    if r.shape[0] == 0 or seg.shape[0] == 0:
        return np.empty((0, 2), dtype=np.int64)
    reach = 0.5 * np.hypot(r[:, LENGTH], r[:, WIDTH])
    lo = np.minimum(seg[:, 0:2], seg[:, 2:4])
    hi = np.maximum(seg[:, 0:2], seg[:, 2:4])
    centre = r[:, None, CX : CY + 1]
    near = np.all(
        (centre >= lo[None] - reach[:, None, None]) & (centre <= hi[None] + reach[:, None, None]),
        axis=2,
    )
    ri, si = np.nonzero(near)
    if ri.size == 0:
        return np.empty((0, 2), dtype=np.int64)
    c, s = np.cos(r[ri, YAW]), np.sin(r[ri, YAW])
    ax, ay = seg[si, 0] - r[ri, CX], seg[si, 1] - r[ri, CY]
    bx, by = seg[si, 2] - r[ri, CX], seg[si, 3] - r[ri, CY]
    # segment in the rectangle frame: p(t) = a + t (b - a), t in [0, 1]
    px, py = c * ax + s * ay, c * ay - s * ax
    dx, dy = (c * bx + s * by) - px, (c * by - s * bx) - py
    hl, hw = 0.5 * r[ri, LENGTH], 0.5 * r[ri, WIDTH]
    t0 = np.zeros(ri.size)
    t1 = np.ones(ri.size)
    inside = np.ones(ri.size, dtype=bool)
    for p0, d, half in ((px, dx, hl), (py, dy, hw)):
        moving = np.abs(d) > 1e-15
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            ta = (-half - p0) / d
            tb = (half - p0) / d
        lo_t = np.where(moving, np.minimum(ta, tb), -np.inf)
        hi_t = np.where(moving, np.maximum(ta, tb), np.inf)
        inside &= moving | (np.abs(p0) < half)  # parallel: must lie strictly between the sides
        t0 = np.maximum(t0, lo_t)
        t1 = np.minimum(t1, hi_t)
    # A piece of positive length strictly inside (touching gives t0 == t1 or a boundary line).
    crossing = inside & ((t1 - t0) * np.hypot(dx, dy) > 1e-9)
    if np.any(crossing):
        mid = 0.5 * (t0 + t1)
        mx, my = px + mid * dx, py + mid * dy
        crossing &= (np.abs(mx) < hl) & (np.abs(my) < hw)
    pairs = np.column_stack([ri[crossing], si[crossing]]).astype(np.int64)
    return pairs
