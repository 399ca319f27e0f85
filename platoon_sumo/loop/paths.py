"""The route paths the members drive, stacked for kernels that serve every member in
one call."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.path import RoutePath


class PathStack:
    """Paths numbered in the order first met, and any per-point array of theirs
    concatenated with each path's first row (`starts[k]:starts[k + 1]` are path k's).
    A new path renumbers nothing and restacks on the next request; the paths are kept
    alive here, so their ids stay unique."""

    def __init__(self) -> None:
        self._paths: list[RoutePath] = []
        self._number: dict[int, int] = {}
        self._stacks: dict[str, tuple[NDArray[np.float64], NDArray[np.int64]]] = {}

    def number(self, path: RoutePath) -> int:
        k = self._number.get(id(path))
        if k is None:
            k = self._number[id(path)] = len(self._paths)
            self._paths.append(path)
            self._stacks.clear()
        return k

    def stacked(
        self, name: str, rows_of: Callable[[RoutePath], NDArray[np.float64]]
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """`rows_of(path)` of every path numbered so far, concatenated (C-contiguous
        float64), and the paths' first rows (one more: the end); kept as `name` until a
        new path comes."""
        found = self._stacks.get(name)
        if found is None:
            parts = [rows_of(p) for p in self._paths]
            starts = np.zeros(len(parts) + 1, dtype=np.int64)
            np.cumsum([len(a) for a in parts], out=starts[1:])
            rows = np.ascontiguousarray(np.concatenate(parts), dtype=np.float64)
            found = self._stacks[name] = (rows, starts)
        return found
