"""A user's controller that, from `from_s` on, returns something a vehicle cannot
execute (chosen by `returns`): the loop must stop with the plug-in, vehicle and time.

Loaded as `bad_command:BadCommand` when the tests put this folder on sys.path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from platoon_sumo.control import Command, Observation

WHAT = {
    "nan_speed": lambda: Command(math.nan),
    "negative_speed": lambda: Command(-3.0),
    "infinite_speed": lambda: Command(math.inf),
    "nan_yaw_rate": lambda: Command(5.0, yaw_rate_radps=math.nan),
    "infinite_heading": lambda: Command(5.0, heading_rad=math.inf),
    "lane_change_two": lambda: Command(5.0, lane_change=2),
    "none": lambda: None,
    "text": lambda: "fast",
}


@dataclass(frozen=True)
class BadCommandParams:
    returns: str = "nan_speed"
    from_s: float = 2.0


class BadCommand:
    Params: ClassVar[type[BadCommandParams]] = BadCommandParams

    def __init__(self, params: BadCommandParams | None = None) -> None:
        self.params = params or BadCommandParams()

    def reset(self) -> None:
        pass

    def step(self, observation: Observation) -> Any:
        if observation.time_s >= self.params.from_s - 1e-9:
            return WHAT[self.params.returns]()
        return Command(5.0)
