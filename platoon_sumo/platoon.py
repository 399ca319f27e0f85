"""Platoons as ordered members: who follows whom, and what a follower truly sees of it.

These helpers serve metrics and events, never control: followers find their
predecessor with their own sensor. A member's predecessor is the nearest member ahead
in the platoon's order that is still in the network.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Protocol


class Member(Protocol):
    @property
    def id(self) -> str: ...

    @property
    def platoon_id(self) -> str: ...

    @property
    def index(self) -> int: ...


def predecessor_ids(members: Iterable[Member]) -> dict[str, str | None]:
    """Each member's predecessor (None for the first member still in the network)."""
    by_platoon: dict[str, list[Member]] = {}
    for m in members:
        by_platoon.setdefault(m.platoon_id, []).append(m)
    result: dict[str, str | None] = {}
    for group in by_platoon.values():
        group.sort(key=lambda m: m.index)
        previous: str | None = None
        for m in group:
            result[m.id] = previous
            previous = m.id
    return result


def bumper_gap_m(follower_rect: Sequence[float], leader_rect: Sequence[float]) -> float:
    """Distance from the follower's front-bumper centre to the leader's rear-bumper centre.

    Rectangles are `(centre_x, centre_y, yaw, length, width)`; on a straight lane this is
    the bumper-to-bumper gap SUMO reports.
    """
    fx = follower_rect[0] + 0.5 * follower_rect[3] * math.cos(follower_rect[2])
    fy = follower_rect[1] + 0.5 * follower_rect[3] * math.sin(follower_rect[2])
    lx = leader_rect[0] - 0.5 * leader_rect[3] * math.cos(leader_rect[2])
    ly = leader_rect[1] - 0.5 * leader_rect[3] * math.sin(leader_rect[2])
    return math.hypot(lx - fx, ly - fy)


@dataclass(frozen=True)
class PlatoonEvent:
    """A change in a platoon's structure, for the run summary."""

    time_s: float
    platoon_id: str
    follower_id: str
    kind: str
    """`split`, `reformation` or `cut_in`."""
    other_id: str
    """The predecessor (split, re-formation) or the vehicle that cut in."""


@dataclass
class _LinkState:
    linked: bool = False
    since_s: float = 0.0
    split: bool = False
    ever_linked: bool = False
    intruder: str | None = None


class LinkMonitor:
    """Turns per-step link observations into split / re-formation / cut-in events.

    A follower is linked while it perceives its predecessor. Losing it for `hold_s`
    counts one split; perceiving it again for `hold_s` after a split counts one
    re-formation (the first link at start-up is formation, not re-formation). A vehicle
    from outside the platoon that becomes the nearest vehicle ahead of a follower,
    closer than its predecessor, counts one cut-in.
    """

    def __init__(self, hold_s: float = 1.0):
        self.hold_s = hold_s
        self._state: dict[str, _LinkState] = {}

    def observe(
        self,
        time_s: float,
        platoon_id: str,
        follower_id: str,
        predecessor_id: str,
        linked: bool,
        intruder_id: str | None,
    ) -> list[PlatoonEvent]:
        s = self._state.setdefault(follower_id, _LinkState(since_s=time_s))
        new: list[PlatoonEvent] = []
        if linked != s.linked:
            s.linked, s.since_s = linked, time_s
        held = time_s - s.since_s >= self.hold_s - 1e-9
        if s.linked and held and not s.ever_linked:
            s.ever_linked = True
        elif s.linked and held and s.split:
            s.split = False
            new.append(PlatoonEvent(time_s, platoon_id, follower_id, "reformation", predecessor_id))
        elif not s.linked and held and s.ever_linked and not s.split:
            s.split = True
            new.append(PlatoonEvent(time_s, platoon_id, follower_id, "split", predecessor_id))
        if intruder_id is not None and intruder_id != s.intruder:
            new.append(PlatoonEvent(time_s, platoon_id, follower_id, "cut_in", intruder_id))
        s.intruder = intruder_id
        return new

    def forget(self, follower_id: str) -> None:
        self._state.pop(follower_id, None)
