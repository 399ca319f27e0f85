"""Platoons as ordered members: who follows whom, and what a follower truly sees of it.

These helpers serve metrics and recording, never control: followers find their
predecessor with their own sensor. A member's predecessor is the nearest member ahead
in the platoon's order that is still in the network.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.sensors.laser import LaserConfig, LaserScan
from platoon_sumo.sensors.raycast import cast_rays


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


def bumper_gap_m(follower_rect: NDArray[np.float64], leader_rect: NDArray[np.float64]) -> float:
    """Distance from the follower's front-bumper centre to the leader's rear-bumper centre.

    Rectangles are `(centre_x, centre_y, yaw, length, width)`; on a straight lane this is
    the bumper-to-bumper gap SUMO reports.
    """
    fx = follower_rect[0] + 0.5 * follower_rect[3] * math.cos(follower_rect[2])
    fy = follower_rect[1] + 0.5 * follower_rect[3] * math.sin(follower_rect[2])
    lx = leader_rect[0] - 0.5 * leader_rect[3] * math.cos(leader_rect[2])
    ly = leader_rect[1] - 0.5 * leader_rect[3] * math.sin(leader_rect[2])
    return math.hypot(lx - fx, ly - fy)


def rays_on_target(scan: LaserScan, config: LaserConfig, target: NDArray[np.float64]) -> int:
    """How many rays of `scan` return from `target` (a rectangle) rather than from anything
    in front of it.

    The target alone is cast exactly; a ray counts where the scan's reading agrees with
    that distance (within 4 sigma of the range noise). Dropouts do not count.
    """
    alone = cast_rays(
        (scan.origin_x_m, scan.origin_y_m), scan.heading_rad, config, rectangles=target[None, :]
    )
    tolerance = max(4.0 * config.noise_std_m, 1e-6)
    hit = np.isfinite(alone)
    return int(np.count_nonzero(np.abs(scan.ranges[hit] - alone[hit]) <= tolerance))
