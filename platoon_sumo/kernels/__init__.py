"""Compiled kernels (numba ``@njit(cache=True)``) for the per-step hot paths.

Pure functions on arrays and numbers, no Python objects: route-path projection and the
speed-profile look-ahead (``path.py``), scan segmentation and rear fitting
(``perception.py``), the laser follower's scan and trail geometry (``follower.py``), the
laser scanner's ray casting (``raycast.py``), the predecessor-trail metric (``trail.py``),
the world read's distance filter (``neighbours.py``) and the supervisor's speed bounds
(``supervision.py``). The modules that use them keep their public API; the kernels do
the same arithmetic as the numpy or Python code they replace, to floating-point rounding
(each is tested against that code kept as an oracle).

Each kernel is compiled on its first call and cached next to its module
(``__pycache__``, numba's ``cache=True``), so later processes load it instead of
compiling it again. numba checks only the kernel's own source file against its cache,
not the kernels it calls in other modules: in a source checkout, after editing a kernel
that another module's kernel calls, delete ``platoon_sumo/kernels/__pycache__/*.nb[ci]``
(an install copies every file anew, so it compiles every kernel again).
"""

from __future__ import annotations

from typing import Any


def in_cache(kernel: Any) -> bool | None:
    """Whether numba's cache holds a compiled version of `kernel` (a ``njit(cache=True)``
    function) for its present source; None where the cache cannot be read (numba's
    internals, which this reads, changed). The first run after an install compiles every
    kernel it calls, which takes about a minute on 2 cores."""
    try:
        return bool(kernel._cache._cache_file._load_index())
    except Exception:  # internals of numba: no answer, not an error
        return None
