"""The ray caster's run evaluation as it was in numpy (before the compiled kernel),
kept as the oracle of `platoon_sumo.kernels.raycast.evaluate_runs`: the same minimum
per ray and the same lowest identity at it, evaluated in chunks of rows."""

from __future__ import annotations

import numpy as np

from platoon_sumo.sensors.laser import LaserConfig
from platoon_sumo.sensors.raycast import FloatArray, IntArray

_ROWS_PER_CHUNK = 1 << 16
_UNSET = np.iinfo(np.intp).max


def evaluate_runs(
    out: FloatArray,
    config: LaserConfig,
    sensor: IntArray,
    run_first: IntArray,
    counts: IntArray,
    num: FloatArray,
    ex: FloatArray,
    ey: FloatArray,
    hits: IntArray | None = None,
    ids: IntArray | None = None,
) -> None:
    """For every run (a segment and the consecutive rays that hit it) write the hit
    distances into ``out`` (flat, sensor-major), keeping the minimum per ray; with
    ``hits`` and ``ids`` (the obstacle of each run) also the lowest identity among the
    runs at that minimum."""
    if counts.size == 0:
        return
    n = config.samples
    n_sensors = out.size // n
    angles = config.angles_rad
    cos_all = np.tile(np.cos(angles), n_sensors)
    sin_all = np.tile(np.sin(angles), n_sensors)
    flat_first = sensor * n + run_first
    ends = np.cumsum(counts)
    starts = ends - counts
    lane = np.arange(min(int(ends[-1]), _ROWS_PER_CHUNK + int(counts.max())), dtype=np.intp)
    seen = np.zeros(n_sensors, dtype=bool)  # sensors with rows in an earlier chunk
    lo = 0
    while lo < counts.size:
        # runs [lo, hi) hold at most _ROWS_PER_CHUNK rows (or a single larger run)
        hi = int(np.searchsorted(ends, starts[lo] + _ROWS_PER_CHUNK, side="right"))
        hi = max(hi, lo + 1)
        c = counts[lo:hi]
        total = int(ends[hi - 1] - starts[lo])
        flat = lane[:total] - np.repeat(starts[lo:hi] - starts[lo] - flat_first[lo:hi], c)
        denom = cos_all.take(flat) * np.repeat(ey[lo:hi], c)
        denom -= sin_all.take(flat) * np.repeat(ex[lo:hi], c)
        t = np.repeat(num[lo:hi], c)
        t /= denom
        if hits is None or ids is None:
            np.minimum.at(out, flat, t)
        else:
            # only rays of sensors met in an earlier chunk can already hold an identity
            old = seen[sensor[lo:hi]]
            seen[sensor[lo:hi]] = True
            recheck = np.flatnonzero(np.repeat(old, c)) if old.any() else None
            min_with_identity(out, hits, flat, t, np.repeat(ids[lo:hi], c), recheck)
        lo = hi


def min_with_identity(
    out: FloatArray,
    hits: IntArray,
    flat: IntArray,
    t: FloatArray,
    ids: IntArray,
    recheck: IntArray | None,
) -> None:
    """``minimum.at(out, flat, t)``, and in ``hits`` the lowest ``ids`` at each minimum.

    ``recheck``: the rows whose ray may hold an identity from an earlier chunk (None:
    every ray of these rows is still ``_UNSET``). ``ids`` is overwritten.
    """
    before = None if recheck is None else out.take(flat[recheck])
    np.minimum.at(out, flat, t)
    win = t == out.take(flat)
    if recheck is not None and before is not None:
        # a ray whose minimum dropped here forgets the identity of its old minimum
        dropped = recheck[t[recheck] < before]
        hits[flat[dropped]] = _UNSET
    np.putmask(ids, ~win, _UNSET)
    np.minimum.at(hits, flat, ids)
