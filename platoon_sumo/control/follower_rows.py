"""Pooled rows of the arrays laser followers keep between steps, so that one kernel call
steps them all (``LaserFollower.step_many``).

A follower that joins a pool gets a row of each array and keeps working on views of its
rows: its own step (``LaserFollower.step``) and the batched one read and write the same
numbers. When the pool grows, the arrays are copied into larger ones and every live
member is pointed at its rows again (``bind``); a member that is garbage-collected gives
its row back.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class PoolMember(Protocol):
    def bind(self, pool: FollowerRows, slot: int) -> None:
        """Point the member's arrays at its rows (after joining, and after a growth)."""


class FollowerRows:
    """Rows of per-follower arrays of fixed shapes (``shapes``: name -> the shape of one
    row), for the followers whose scans have the same number of rays and whose trails
    the same capacity."""

    def __init__(self, shapes: dict[str, tuple[int, ...]], capacity: int = 8):
        self.shapes = dict(shapes)
        self.arrays: dict[str, FloatArray] = {
            name: np.zeros((capacity, *shape)) for name, shape in self.shapes.items()
        }
        self._members: list[weakref.ref[PoolMember] | None] = [None] * capacity
        self._free = list(range(capacity - 1, -1, -1))

    def join(self, member: PoolMember) -> int:
        """A row for `member` (its arrays are then pointed at it with ``bind``)."""
        if not self._free:
            self._grow()
        slot = self._free.pop()
        self._members[slot] = weakref.ref(member)
        weakref.finalize(member, _release(self, slot))
        member.bind(self, slot)
        return slot

    def _grow(self) -> None:
        old = len(self._members)
        for name, array in self.arrays.items():
            larger = np.zeros((2 * old, *self.shapes[name]))
            larger[:old] = array
            self.arrays[name] = larger
        self._members.extend([None] * old)
        self._free.extend(range(2 * old - 1, old - 1, -1))
        for slot, ref in enumerate(self._members[:old]):
            member = ref() if ref is not None else None
            if member is not None:
                member.bind(self, slot)

    def release(self, slot: int) -> None:
        self._members[slot] = None
        self._free.append(slot)


def _release(pool: FollowerRows, slot: int) -> Callable[[], None]:
    # a weak reference to the pool: a finalizer must not keep it alive
    ref = weakref.ref(pool)

    def release() -> None:
        found = ref()
        if found is not None:
            found.release(slot)

    return release


class PathTables:
    """Route paths numbered in the order first met, with their kernel arrays appended to
    growing tables (each name one table; ``starts(name)[k]:starts(name)[k + 1]`` are
    path k's rows). Paths are held here; when many more are held than a call uses (the
    routes of vehicles gone), the tables start again from that call's paths."""

    def __init__(self, names: tuple[str, ...]):
        self._names = names
        self._clear()

    def _clear(self) -> None:
        self._paths: list[object] = []
        self._number: dict[int, int] = {}
        self._tables: dict[str, np.ndarray] = {}
        self._used: dict[str, int] = dict.fromkeys(self._names, 0)
        self._starts: dict[str, list[int]] = {name: [0] for name in self._names}
        self._start_arrays: dict[str, NDArray[np.int64]] = {}

    def numbers(
        self, paths: list[object], arrays_of: Callable[[object], tuple[np.ndarray, ...]]
    ) -> list[int]:
        """The numbers of `paths` (one per follower), adding the new ones with
        `arrays_of(path)` (one array per name, rows first)."""
        if len(self._paths) > 64 and len(self._paths) > 4 * len(set(map(id, paths))):
            self._clear()
        number = self._number
        out = []
        for path in paths:
            k = number.get(id(path))
            if k is None:
                k = self._add(path, arrays_of(path))
            out.append(k)
        return out

    def _add(self, path: object, arrays: tuple[np.ndarray, ...]) -> int:
        k = self._number[id(path)] = len(self._paths)
        self._paths.append(path)
        for name, rows in zip(self._names, arrays, strict=True):
            used = self._used[name]
            table = self._tables.get(name)
            if table is None or used + len(rows) > len(table):
                size = max(2 * (used + len(rows)), 64)
                larger = np.zeros((size, *rows.shape[1:]), dtype=rows.dtype)
                if table is not None:
                    larger[:used] = table[:used]
                table = self._tables[name] = larger
            table[used : used + len(rows)] = rows
            self._used[name] = used + len(rows)
            self._starts[name].append(used + len(rows))
        self._start_arrays.clear()
        return k

    def table(self, name: str) -> np.ndarray:
        return self._tables[name]

    def starts(self, name: str) -> NDArray[np.int64]:
        """Where each path's rows of table `name` start (and the last one ends): kept
        until a path is added (the kernels only read it; a read-only array would be
        another type to numba)."""
        found = self._start_arrays.get(name)
        if found is None:
            found = self._start_arrays[name] = np.array(self._starts[name], dtype=np.int64)
        return found
