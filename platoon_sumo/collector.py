"""Python's cyclic garbage collector around a run's two phases.

Building a run (the network, the routes, the paths, SUMO's bindings) makes hundreds of
thousands of objects that all live as long as the run; stepping it makes short-lived
ones. Left alone, the collector's full passes walk every object a few times while the
heap grows and again during the steps, and find next to nothing: on the DRT city
(`city_platoons`, 200 s) the two full passes during the steps took 0.33 s of the run's
CPU and freed a few hundred objects; frozen, one pass of 10-20 ms is left. Pausing the
collector while the plan is built saves less: the allocations owe their passes when it
runs again (`tools/gc_passes.py`, docs/performance.md session 37). Both blocks leave the
collector as they found it.
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator

#: Objects the interpreter itself keeps frozen, read when this module is first imported:
#: none on CPython 3.11 and 3.13; CPython 3.12 starts with the built-in types' base and
#: MRO tuples there (375 on 3.12.1, all immortal), and a full collection puts them back
#: after an unfreeze. (Read after an unfreeze and before the next full collection, it
#: is 0 on 3.12, and the block then leaves the objects unfrozen: slower, not wrong.)
INTERPRETER_FROZEN = gc.get_freeze_count()


@contextlib.contextmanager
def collector_paused() -> Iterator[None]:
    """No collection while the block builds objects that live on (`gc.disable`); the
    collector runs again after it if it ran before."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


@contextlib.contextmanager
def existing_objects_frozen() -> Iterator[None]:
    """The objects that exist when the block starts are left out of the collector's
    passes until it ends (`gc.freeze`; garbage among them is collected after it). Does
    nothing while a caller holds objects frozen itself (more than the interpreter's
    own, `INTERPRETER_FROZEN`), whose freeze it would undo. Its end hands every frozen
    object back, the interpreter's own too (`gc.unfreeze` has no partial form; they are
    immortal and few): the guard once read 3.12's own as a caller's and never froze."""
    if gc.get_freeze_count() > INTERPRETER_FROZEN:
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
