"""Exact planar ray casting for the laser scanner, batched over many sensors (compiled
kernels in ``platoon_sumo.kernels.raycast``).

Why it is fast without giving up exactness:

* Everything is one ray-segment kernel. A rectangle contributes only the edges that face
  the sensor (at most 2; all 4 when the sensor is inside it): the first hit on a convex
  shape from outside is always on a facing edge, so the other edges can never win.
* A segment seen from the sensor covers a wedge of directions. Rays are evenly spaced,
  so the wedge maps to a contiguous run of ray indices, and only those (ray, segment)
  pairs are evaluated: every evaluated pair is a hit, none is wasted on a miss. The
  work is the sum of the obstacles' angular sizes, not rays x segments.
* Adjacent edges of a rectangle share their corner floats, so the ray-index bound of a
  corner is computed identically for both edges: no ray leaks through a corner.
* A hashed uniform grid, built once per call, gives each sensor the obstacles within
  ``range_max`` of it, so the cost depends on what is near each sensor only.
* Two compiled passes per call, with no Python loop per sensor and no temporary array
  per (ray, segment) pair: ``candidate_edges`` lists each sensor's facing edges and
  near segments in its own frame (into scratch tables kept from call to call), numpy
  takes the bearings of their ends (``arctan2``), and ``evaluate_edges`` walks each
  sensor's runs of rays into its row of readings, keeping the minimum per ray, then
  turns the row into REP 117 readings while it is in cache.

Hit identities (``return_hits=True``): every evaluated pair carries the index of its
obstacle; a ray keeps the identity of its minimum, and at an equal distance the lower
index, so a tie (a shared corner, a duplicated obstacle) resolves to the lower index
whatever the order of evaluation or the batching. The distances take the same path as
without identities, so the ranges are bit-identical.

The kernels do the arithmetic of the numpy implementation they replaced, operation by
operation (it is kept in ``tests/sensors/reference_raycast.py`` as their oracle: the
same readings and identities on random scenes). The bearings stay numpy's because its
SIMD ``arctan2`` and libm's differ in the last bit now and then, and that bit decides
whether a ray exactly through a corner belongs to an edge.

Hit distance along a ray of unit direction d from the sensor to the line through a with
direction e: ``t = cross(a, e) / cross(d, e)``.
"""

from __future__ import annotations

import threading
from functools import lru_cache
from statistics import NormalDist
from typing import Literal, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from platoon_sumo.geometry import as_rectangles
from platoon_sumo.kernels.raycast import (
    GEO_ROWS,
    INT_ROWS,
    candidate_edges,
    evaluate_edges,
)
from platoon_sumo.sensors.laser import LaserConfig

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Obstacles farther than range_max + this are culled; the slack keeps culling from
#: ever disagreeing with the kernel's own rounding at the range limit.
_CULL_SLACK_M = 1e-6
#: Hit identity of a ray without a return (``+inf`` or a ``NaN`` dropout).
NO_RETURN = -1
#: Working identity of a ray no evaluated pair has won yet (above every real index).
_UNSET = np.iinfo(np.intp).max


@overload
def cast_rays(
    origin: ArrayLike,
    heading: float,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: Literal[False] = ...,
) -> FloatArray: ...


@overload
def cast_rays(
    origin: ArrayLike,
    heading: float,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: Literal[True],
) -> tuple[FloatArray, IntArray]: ...


@overload
def cast_rays(
    origin: ArrayLike,
    heading: float,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: bool,
) -> FloatArray | tuple[FloatArray, IntArray]: ...


def cast_rays(
    origin: ArrayLike,
    heading: float,
    config: LaserConfig,
    rectangles: ArrayLike | None = None,
    segments: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    *,
    return_hits: bool = False,
) -> FloatArray | tuple[FloatArray, IntArray]:
    """Ranges [m] of one scan, shape ``(samples,)``, REP 117 conventions.

    ``origin`` is the sensor position (x, y) [m], ``heading`` its forward direction
    [rad, CCW from +x]. ``rectangles`` is ``(N, 5)``: centre_x, centre_y, yaw, length
    (along yaw), width; ``segments`` is ``(M, 4)``: x1, y1, x2, y2. Without noise each
    finite reading is the exact distance to the first surface on the ray (to rounding).

    A sensor strictly inside a rectangle sees that rectangle's inner walls (usually
    closer than range_min, so ``-inf``); a sensor exactly on a surface reads 0 on every
    ray. Noise and dropouts need ``rng`` (see ``apply_noise``).

    With ``return_hits=True`` the result is ``(ranges, hits)``: ``hits`` (intp, same
    shape) names the obstacle each reading comes from: ``i`` for ``rectangles[i]``,
    ``N + j`` for ``segments[j]``, ``NO_RETURN`` (-1) where the reading is ``+inf`` or a
    ``NaN`` dropout; a ``-inf`` reading keeps the identity of the too-close surface.
    Surfaces at exactly the same distance on a ray give the lowest index (a sensor on a
    surface: the lowest surface it touches, on every ray). The ranges and the draws from
    ``rng`` are the same as with ``return_hits=False``.
    """
    origins = np.asarray(origin, dtype=np.float64).reshape(1, 2)
    headings = np.asarray([heading], dtype=np.float64)
    rects, segs = obstacle_arrays(rectangles, segments)
    ranges, hits = _scan(
        origins, headings, config, rects, segs, None, use_grid=False, with_hits=return_hits, rng=rng
    )
    if hits is None:
        return ranges[0]
    return ranges[0], hits[0]


@overload
def scan_many(
    origins: ArrayLike,
    headings: ArrayLike,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    exclude: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: Literal[False] = ...,
) -> FloatArray: ...


@overload
def scan_many(
    origins: ArrayLike,
    headings: ArrayLike,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    exclude: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: Literal[True],
) -> tuple[FloatArray, IntArray]: ...


@overload
def scan_many(
    origins: ArrayLike,
    headings: ArrayLike,
    config: LaserConfig,
    rectangles: ArrayLike | None = ...,
    segments: ArrayLike | None = ...,
    exclude: ArrayLike | None = ...,
    rng: np.random.Generator | None = ...,
    *,
    return_hits: bool,
) -> FloatArray | tuple[FloatArray, IntArray]: ...


def scan_many(
    origins: ArrayLike,
    headings: ArrayLike,
    config: LaserConfig,
    rectangles: ArrayLike | None = None,
    segments: ArrayLike | None = None,
    exclude: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    *,
    return_hits: bool = False,
) -> FloatArray | tuple[FloatArray, IntArray]:
    """Ranges of K sensors at once, shape ``(K, samples)``.

    ``exclude[k]`` is the index of the rectangle that is sensor k's own vehicle (-1 for
    none). Row k equals ``cast_rays`` for sensor k with that rectangle removed; with
    noise, one generator gives the same draws batched or one sensor at a time.

    ``return_hits=True`` returns ``(ranges, hits)``, ``hits`` as in ``cast_rays`` with
    the indices into the full ``rectangles`` and ``segments`` passed here (row k never
    names ``exclude[k]``).
    """
    pos = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    head = np.asarray(headings, dtype=np.float64).reshape(-1)
    if head.shape[0] != pos.shape[0]:
        raise ValueError(f"headings: expected {pos.shape[0]} values, got {head.shape[0]}")
    excl = None
    if exclude is not None:
        excl = np.asarray(exclude, dtype=np.intp).reshape(-1)
        if excl.shape[0] != pos.shape[0]:
            raise ValueError(f"exclude: expected {pos.shape[0]} values, got {excl.shape[0]}")
    rects, segs = obstacle_arrays(rectangles, segments)
    ranges, hits = _scan(
        pos, head, config, rects, segs, excl, use_grid=True, with_hits=return_hits, rng=rng
    )
    if hits is None:
        return ranges
    return ranges, hits


def apply_noise(
    ranges: FloatArray, config: LaserConfig, rng: np.random.Generator | None
) -> FloatArray:
    """Add Gaussian range noise to valid readings and NaN dropouts, in place.

    Each scan draws one ``(2, samples)`` block of standard normals: row 0 is the range
    noise, row 1 decides dropouts (``z < Phi^-1(p)`` has probability p). Drawing one
    block per scan is what makes batched and per-sensor scans reproduce each other.
    Noisy readings are clipped to [range_min, range_max] so finite stays in range.
    """
    if config.noise_std_m == 0.0 and config.dropout_prob == 0.0:
        return ranges
    if rng is None:
        raise ValueError(
            "rng: a numpy.random.Generator is required when noise_std_m > 0 or "
            "dropout_prob > 0 (e.g. numpy.random.default_rng(seed))"
        )
    k, n = ranges.shape
    z = rng.standard_normal((k, 2, n))
    if config.noise_std_m > 0.0:
        valid = np.isfinite(ranges)
        noisy = ranges[valid] + config.noise_std_m * z[:, 0, :][valid]
        ranges[valid] = np.clip(noisy, config.range_min_m, config.range_max_m)
    if config.dropout_prob > 0.0:
        threshold = NormalDist().inv_cdf(config.dropout_prob)
        ranges[z[:, 1, :] < threshold] = np.nan
    return ranges


# ----------------------------------------------------------------------------- internals


def obstacle_arrays(
    rectangles: ArrayLike | None, segments: ArrayLike | None
) -> tuple[FloatArray, FloatArray]:
    """Validated ``(N, 5)`` rectangles and ``(M, 4)`` segments; None or empty gives 0 rows."""
    rects = np.empty((0, 5))
    if rectangles is not None and np.size(rectangles):
        rects = as_rectangles(rectangles)
    segs = np.empty((0, 4))
    if segments is not None and np.size(segments):
        segs = np.asarray(segments, dtype=np.float64)
        if segs.ndim != 2 or segs.shape[1] != 4:
            raise ValueError(f"segments: expected shape (M, 4), got {segs.shape}")
    return rects, segs


def _finish(raw: FloatArray, config: LaserConfig, rng: np.random.Generator | None) -> FloatArray:
    """Raw first-hit distances -> REP 117 readings, then noise and dropouts."""
    if config.range_min_m == 0.0:
        np.maximum(raw, 0.0, out=raw)  # rounding can give -1e-17 for a touching surface
    raw[raw > config.range_max_m] = np.inf
    raw[raw < config.range_min_m] = -np.inf
    return apply_noise(raw, config, rng)


def _no_return(hits: IntArray, ranges: FloatArray) -> IntArray:
    """Final identities: ``NO_RETURN`` where the reading is ``+inf`` or ``NaN``."""
    np.putmask(hits, ~(ranges < np.inf), NO_RETURN)  # False for +inf and NaN only
    return hits


@lru_cache(maxsize=16)
def _ray_tables(config: LaserConfig) -> tuple[FloatArray, FloatArray]:
    """Cosines and sines of the rays' angles (sensor frame)."""
    angles = config.angles_rad
    return np.cos(angles), np.sin(angles)


def _scan(
    sensors: FloatArray,
    headings: FloatArray,
    config: LaserConfig,
    rects: FloatArray,
    segs: FloatArray,
    exclude: IntArray | None,
    use_grid: bool,
    with_hits: bool,
    rng: np.random.Generator | None,
) -> tuple[FloatArray, IntArray | None]:
    """Readings (K, samples) and with ``with_hits`` their identities: the two compiled
    passes of ``kernels.raycast`` (the candidate edges, then the rays, REP 117 included)
    around numpy's ``arctan2`` of the edges' ends, then noise and dropouts."""
    k, n = sensors.shape[0], config.samples
    exclude = np.full(k, -1, dtype=np.intp) if exclude is None else exclude
    yaw = rects[:, 2]
    work = _WORKSPACE
    starts, touch, work.geo, work.ints = candidate_edges(
        np.ascontiguousarray(sensors), np.cos(headings), np.sin(headings),
        np.ascontiguousarray(rects), np.cos(yaw), np.sin(yaw), np.ascontiguousarray(segs),
        np.ascontiguousarray(exclude), config.range_max_m + _CULL_SLACK_M, use_grid, _UNSET,
        work.geo, work.ints,
    )  # fmt: skip
    geo, used = work.geo, int(starts[-1])
    np.arctan2(geo[1, :used], geo[0, :used], out=geo[7, :used])
    np.arctan2(geo[3, :used], geo[2, :used], out=geo[8, :used])
    if with_hits:
        # readings and identities in one allocation: requested and freed call after
        # call, one block comes back from the allocator as it was, where two separate
        # ones came back as fresh pages (page faults: ~3 µs per 1081-ray scan measured)
        block = np.empty((2, k, n))
        ranges, hits = block[0], block[1].view(np.intp)
    else:
        ranges, hits = np.empty((k, n)), np.empty((0, n), dtype=np.intp)
    cos_a, sin_a = _ray_tables(config)
    evaluate_edges(
        starts, touch, work.ints, geo, config.angle_min_rad, config.angle_increment_rad,
        cos_a, sin_a, config.range_min_m, config.range_max_m, ranges, hits, with_hits,
        _UNSET, NO_RETURN,
    )  # fmt: skip
    if config.noise_std_m == 0.0 and config.dropout_prob == 0.0:
        return ranges, hits if with_hits else None
    apply_noise(ranges, config, rng)
    return ranges, _no_return(hits, ranges) if with_hits else None


class _Workspace(threading.local):
    """Scratch tables of the candidate edges (``kernels.raycast.GEO_ROWS`` and
    ``INT_ROWS``), kept per thread from call to call: they grow to the largest batch
    seen, and a call does not pay for fresh pages."""

    def __init__(self) -> None:
        self.geo = np.empty((len(GEO_ROWS), 1024))
        self.ints = np.empty((len(INT_ROWS), 1024), dtype=np.int64)


_WORKSPACE = _Workspace()
