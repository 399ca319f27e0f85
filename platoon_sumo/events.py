"""The run's event stream: one typed record per thing that happened, appended by the loop.

Every count in `summary.json`, `vehicles.csv` and `platoons.csv` and every row of
`events.csv` comes from these records, so online and offline numbers agree by
construction. Each kind is defined once, in docs/metrics.md ("Events").
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Generic, TypeVar


class EventKind(str, Enum):
    """What happened (the `kind` column of events.csv)."""

    COLLISION = "collision"
    """Footprints of a platoon vehicle and another vehicle began to overlap."""
    WALL_CONTACT = "wall_contact"
    """A platoon vehicle's footprint began to cross a wall, kerb or building."""
    SUMO_COLLISION = "sumo_collision"
    """SUMO reported a new collision (its lane-based check), any vehicles."""
    TELEPORT = "teleport"
    """SUMO started teleporting a vehicle (a jam it gave up on)."""
    GRIDLOCK = "gridlock"
    """A vehicle (any) has stood still for `outputs.gridlock_after_s`, not at a stop of
    its schedule nor queued at a red light."""
    RED_LIGHT = "red_light"
    """A platoon vehicle crossed a stop line on red or red-yellow."""
    STANDOFF = "standoff"
    """A platoon vehicle SUMO held at an unsignalised link took the junction, every
    vehicle it yielded to standing still too (a circle of right of way)."""
    EMERGENCY_BRAKING = "emergency_braking"
    """The supervisor's last-resort brake began to act on a platoon vehicle."""
    SUMO_SPEED_CAP = "sumo_speed_cap"
    """Lane actuation: SUMO's safety layer began to hold a vehicle below its command."""
    SPLIT = "split"
    """A follower lost its predecessor for the hold time."""
    REFORMATION = "reformation"
    """A follower saw its predecessor again for the hold time after a split."""
    CUT_IN = "cut_in"
    """A vehicle from outside the platoon became a follower's nearest vehicle ahead."""
    DEPARTED = "departed"
    """A platoon vehicle entered the network."""
    ARRIVED = "arrived"
    """A platoon vehicle reached the end of its route."""
    REMOVED = "removed"
    """A platoon vehicle was taken out because SUMO could not place it any more."""


#: The other party of a contact with static geometry (walls, kerbs, buildings).
WALL = "<wall>"


@dataclass(frozen=True)
class Event:
    """One event. `vehicle_id` is the platoon vehicle concerned (for SUMO collisions the
    collider, for teleports and gridlocks the SUMO vehicle); `other_id` the other party (collision
    partner or WALL, SUMO's victim, the predecessor of a split or re-formation, the
    vehicle that cut in, the traffic light of a red-light violation); `detail` a short
    text (link index and state of a light, SUMO's reason for a removal, a collision's
    type, where and how long a vehicle stood, why a contact is whose fault); `at_fault`
    the vehicle that caused a contact (collisions, wall contacts, SUMO collisions; empty
    when undetermined, `platoon_sumo.fault`)."""

    time_s: float
    kind: EventKind
    vehicle_id: str
    other_id: str = ""
    platoon_id: str = ""
    detail: str = ""
    at_fault: str = ""


EVENT_COLUMNS = ("time_s", "kind", "vehicle_id", "other_id", "platoon_id", "detail", "at_fault")


def event_row(event: Event) -> tuple[float, str, str, str, str, str, str]:
    """An event as a row of events.csv, in `EVENT_COLUMNS` order."""
    return (
        round(event.time_s, 6),
        event.kind.value,
        event.vehicle_id,
        event.other_id,
        event.platoon_id,
        event.detail,
        event.at_fault,
    )


def count(events: Iterable[Event], kind: EventKind) -> int:
    return sum(1 for e in events if e.kind is kind)


def of_kind(events: Iterable[Event], *kinds: EventKind) -> list[Event]:
    return [e for e in events if e.kind in kinds]


K = TypeVar("K", bound=Hashable)


class Onset(Generic[K]):
    """Edge detector: which keys are active now that were not at the last update.

    One contact, one cap or one braking episode counts once, when it begins."""

    def __init__(self) -> None:
        self._active: set[K] = set()

    def update(self, active: Iterable[K]) -> list[K]:
        now = set(active)
        new = now - self._active
        self._active = now
        return sorted(new, key=repr) if new else []

    def discard(self, keys: Sequence[K]) -> None:
        self._active.difference_update(keys)
