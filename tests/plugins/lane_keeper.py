"""A test controller for `actuation: lane`: drives at a fixed speed and, from its start,
asks SUMO to keep its lane every step (`Command.keep_lane`), as a laser follower does
while it sees its predecessor in its own lane (or asks nothing with `keep: false`).
Loaded by scenarios as `lane_keeper:LaneKeeper` (the tests put this folder on sys.path)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from platoon_sumo.control import Command, Observation


@dataclass(frozen=True)
class LaneKeeperParams:
    speed_mps: float = 8.0
    keep: bool = True


class LaneKeeper:
    Params: ClassVar[type[LaneKeeperParams]] = LaneKeeperParams

    def __init__(self, params: LaneKeeperParams | None = None):
        self.params = params or LaneKeeperParams()

    def reset(self) -> None:
        pass

    def step(self, observation: Observation) -> Command:
        return Command(self.params.speed_mps, keep_lane=self.params.keep)
