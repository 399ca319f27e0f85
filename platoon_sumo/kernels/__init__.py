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
compiling it again. numba checks a kernel's cache against the kernel's own source file
only, not against the kernels it calls in other files: after an edit of
``perception.py``, ``following.py``'s cached step would still run the old segmentation
(in a source checkout, and after ``pip install .`` over an older install, since numba
compares the files' contents and leaves its cache files behind). So every kernel's
cache is dropped when any kernel source changed (``drop_stale_caches``, when this
package is first imported, before any kernel is loaded).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

#: The digest of the kernel sources the caches in ``__pycache__`` were compiled from.
SOURCES_STAMP = "kernel-sources.sha256"


def drop_stale_caches(directory: Path) -> bool:
    """Delete numba's cache files (``__pycache__/*.nbi``, ``*.nbc``) of the kernels in
    `directory` unless they were compiled from the ``*.py`` files there as they are now
    (their digest in `SOURCES_STAMP`); returns whether it deleted them. A cache folder
    that cannot be written is left alone (numba then keeps its caches elsewhere)."""
    digest = hashlib.sha256()
    for source in sorted(directory.glob("*.py")):
        digest.update(source.name.encode() + b"\0" + source.read_bytes())
    cache, wanted = directory / "__pycache__", digest.hexdigest()
    stamp = cache / SOURCES_STAMP
    try:
        if stamp.read_text(encoding="ascii") == wanted:
            return False
    except (OSError, UnicodeDecodeError):
        pass
    try:
        cache.mkdir(exist_ok=True)
        for compiled in [*cache.glob("*.nbi"), *cache.glob("*.nbc")]:
            compiled.unlink(missing_ok=True)
        written = cache / f"{SOURCES_STAMP}.{os.getpid()}"
        written.write_text(wanted, encoding="ascii")
        os.replace(written, stamp)
    except OSError:
        return False
    return True


drop_stale_caches(Path(__file__).parent)


def in_cache(kernel: Any) -> bool | None:
    """Whether numba's cache holds a compiled version of `kernel` (a ``njit(cache=True)``
    function) for its present source; None where the cache cannot be read (numba's
    internals, which this reads, changed). The first run after an install, or after an
    upgrade that changed a kernel, compiles every kernel it calls: about a minute on 2
    cores."""
    try:
        return bool(kernel._cache._cache_file._load_index())
    except Exception:  # internals of numba: no answer, not an error
        return None
