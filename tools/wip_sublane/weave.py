from __future__ import annotations
import math
from dataclasses import dataclass
from typing import ClassVar
from platoon_sumo.control.base import Command, Observation

@dataclass(frozen=True)
class WeaveParams:
    speed_mps: float = 10.0
    offset_m: float = 0.8
    from_s: float = 15.0

class Weave:
    """Drives at a fixed speed and steers to a lateral offset from its path after `from_s`."""
    Params: ClassVar[type[WeaveParams]] = WeaveParams
    def __init__(self, params: WeaveParams | None = None):
        self.params = params or WeaveParams()
        self._s = None
    def reset(self) -> None:
        self._s = None
    def step(self, obs: Observation) -> Command:
        p = self.params
        s, lat = obs.path.project_sl(obs.x_m, obs.y_m, self._s, 20.0)
        self._s = s
        want = p.offset_m if obs.time_s >= p.from_s else 0.0
        err = obs.yaw_rad - obs.path.heading_at(s)
        err = math.atan2(math.sin(err), math.cos(err))
        return Command(p.speed_mps, -1.5 * err + 0.15 * (want - lat))
