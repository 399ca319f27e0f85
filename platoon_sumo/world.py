"""What the loop knows about the world at one instant: plain records, no SUMO import.

The backend fills them from libsumo; controllers, sensors and recorders read them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.geometry import wrap_angle


@dataclass(frozen=True)
class WorldSnapshot:
    """Every vehicle in the network at one instant. Positions are FRONT BUMPER centres."""

    time_s: float
    ids: tuple[str, ...]
    front_x_m: NDArray[np.float64]
    front_y_m: NDArray[np.float64]
    yaw_rad: NDArray[np.float64]
    length_m: NDArray[np.float64]
    width_m: NDArray[np.float64]
    speed_mps: NDArray[np.float64]
    lane_ids: tuple[str, ...]
    index: dict[str, int] = field(repr=False)

    def __len__(self) -> int:
        return len(self.ids)


def yaw_rates(now: WorldSnapshot, before: WorldSnapshot | None) -> NDArray[np.float64]:
    """Each vehicle's yaw rate over the time from `before` to `now` [rad/s] (rows of
    `now`; 0 for a vehicle `before` did not hold, or without `before`)."""
    rates = np.zeros(len(now))
    if before is None or now.time_s <= before.time_s or not len(before):
        return rates
    then = np.fromiter((before.index.get(vid, -1) for vid in now.ids), np.int64, len(now))
    seen = then >= 0
    turned = wrap_angle(now.yaw_rad[seen] - before.yaw_rad[then[seen]])
    rates[seen] = turned / (now.time_s - before.time_s)
    return rates


#: Signal states at which a driver stops if it can: red, red-yellow, yellow.
STOP_STATES = frozenset("ruy")


@dataclass(frozen=True)
class SignalAhead:
    """The next traffic light on a vehicle's route: link state and distance to its stop line."""

    tls_id: str
    link_index: int
    state: str
    distance_m: float

    @property
    def is_stop(self) -> bool:
        """Red, red-yellow or yellow: a driver stops if it can."""
        return self.state in STOP_STATES


@dataclass(frozen=True)
class VehicleAhead:
    """The vehicle in front on the same route lanes: bumper-to-bumper gap and its speed."""

    vehicle_id: str
    gap_m: float
    speed_mps: float


@dataclass(frozen=True)
class LinkAhead:
    """The junction link at the end of a vehicle's current lane, as SUMO judges it.

    `is_open` and `has_foe` are SUMO's own right-of-way evaluation for this vehicle's
    approach (its gap acceptance against the foes it knows), so yielding with them treats
    platoon vehicles like SUMO's drivers."""

    state: str
    """SUMO link state: `M` major, `m` minor, `=` equal, `s` stop, `w` all-way stop, ..."""
    has_priority: bool
    is_open: bool
    has_foe: bool
    distance_m: float
    """From the front bumper to the end of the lane (where the link starts)."""

    @property
    def must_yield(self) -> bool:
        """A minor approach that SUMO sees closed or contested."""
        return not self.has_priority and (not self.is_open or self.has_foe)


@dataclass(frozen=True)
class LaneChangeAhead:
    """The next lane change on the route and whether the target lane has room for it."""

    distance_m: float
    """From the front bumper to where the sideways move begins."""
    clear: bool
    """No vehicle on the target lane(s) is predicted near us at any point of the move."""
    target_leader: VehicleAhead | None = None
    """During the move: the nearest vehicle ahead on the target lane(s)."""
