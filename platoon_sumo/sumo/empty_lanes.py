"""Junction lanes known to be empty without asking SUMO.

In a city most of the lanes near the platoons are junctions' internal lanes, and almost
all of them are empty at any step (99 % on the DRT city); the world read asked SUMO for
each one's vehicles every step. A vehicle gets onto an internal lane only by driving
onto it: SUMO inserts vehicles and ends teleports on the roads of their routes, never
inside a junction. So an internal lane that was empty at the last step, with every lane
a vehicle could have driven onto it from within one step (the lanes leading into it,
and the ones before those where the lanes between are shorter than a step's drive at
the fastest vehicle type's maximum speed; the lanes beside it on its junction edge, and
theirs) empty too, is empty now. Lanes open to a rail class (which may reverse) are
always asked once a vehicle of such a class has entered the network.

"Empty at the last step" is what the last world read found or inferred; a lane it did
not look at is not known. A platoon vehicle placed by the planar actuation (or a
plug-in moving a vehicle) is not seen this way: the world read asks SUMO for the given
vehicles' own lanes where their lanes were not listed.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Protocol

#: Vehicle classes that may reverse on a bidirectional track (SUMO's rail classes).
REVERSING_CLASSES = frozenset(
    {"rail", "rail_urban", "rail_electric", "rail_fast", "tram", "subway", "cable_car"}
)
#: Added to a step's drive at the fastest maximum speed [m] (rounding of SUMO's
#: position update).
DRIVE_SLACK_M = 0.5


class LaneGraph(Protocol):
    """What `EmptyLanes` reads of SUMO's lanes (libsumo's `lane` domain)."""

    def getLinks(self, laneID: str) -> Iterable[tuple[object, ...]]: ...

    def getLength(self, laneID: str) -> float: ...

    def getAllowed(self, laneID: str) -> Iterable[str]: ...


class EmptyLanes:
    """Which internal lanes of a world read may go unasked (`known_empty`), from what
    the previous read of the step before (or of this step) found (`remember`)."""

    def __init__(self, lanes: LaneGraph, lane_ids: Iterable[str]):
        self._lanes = lanes
        self._lane_ids = tuple(lane_ids)
        self._before: dict[str, list[str]] | None = None
        """The lanes leading into each lane (a link's lane, or its internal lane)."""
        self._beside: dict[str, list[str]] = {}
        """The lanes of each internal edge."""
        self._feeders: dict[str, tuple[str, ...] | None] = {}
        """Per internal lane: the lanes that must have been empty with it (None: asked
        every step), for `_drive_m`."""
        self._drive_m = -1.0
        self._reversing: frozenset[str] = frozenset()
        """The reversing classes among the vehicles in the network."""
        self._empty: frozenset[str] = frozenset()
        self._step = -2

    def known_empty(
        self, step: int, drive_m: float, classes: frozenset[str]
    ) -> tuple[frozenset[str], set[str]]:
        """(The lanes known empty at the step before `step`, or at `step`, as the last
        read left them; an empty set to fill with the lanes this read finds or infers
        empty.) `drive_m`: the farthest a vehicle drives in a step; `classes`: the
        vehicle classes in the network."""
        reversing = classes & REVERSING_CLASSES
        if drive_m != self._drive_m or reversing != self._reversing:
            self._feeders.clear()
            self._drive_m, self._reversing = drive_m, reversing
        empty = self._empty if step - 1 <= self._step <= step else frozenset()
        return empty, set()

    def remember(self, step: int, empty: set[str]) -> None:
        self._empty, self._step = frozenset(empty), step

    def follows_empty(self, lane: str, empty: frozenset[str]) -> bool:
        """Is this lane empty now, given the lanes empty at the last step (`lane` among
        them)? Only an internal lane can be."""
        if lane not in self._feeders:
            self._feeders[lane] = self._feeders_of(lane)
        feeders = self._feeders[lane]
        return feeders is not None and all(f in empty for f in feeders)

    def _feeders_of(self, lane: str) -> tuple[str, ...] | None:
        if not lane.startswith(":") or not self._reversing.isdisjoint(self._lanes.getAllowed(lane)):
            return None
        before = self._graph()
        beside = self._beside.get(lane.rpartition("_")[0], [lane])
        if not any(before.get(one) for one in beside):
            return None  # not known how vehicles get onto it: asked
        # each lane leading in, with how far a vehicle at its end is from this lane
        ahead_m: dict[str, float] = {}
        for one in beside:
            for previous in before.get(one, ()):
                ahead_m[previous] = 0.0
        stack = list(ahead_m)
        reach = self._drive_m + DRIVE_SLACK_M
        while stack:
            here = stack.pop()
            onward = ahead_m[here] + float(self._lanes.getLength(here))
            if onward > reach:  # a step's drive does not cross it: nothing from before it
                continue
            for previous in before.get(here, ()):
                if onward < ahead_m.get(previous, math.inf):
                    ahead_m[previous] = onward
                    stack.append(previous)
        return tuple(sorted((set(beside) | set(ahead_m)) - {lane}))

    def _graph(self) -> dict[str, list[str]]:
        if self._before is None:
            before: dict[str, list[str]] = {}
            for lane in self._lane_ids:
                if lane.startswith(":"):
                    self._beside.setdefault(lane.rpartition("_")[0], []).append(lane)
                for link in self._lanes.getLinks(lane):
                    successor, via = str(link[0]), str(link[4])
                    if via:
                        before.setdefault(via, []).append(lane)
                        before.setdefault(successor, []).append(via)
                    else:
                        before.setdefault(successor, []).append(lane)
            self._before = before
        return self._before
