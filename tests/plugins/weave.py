"""A test controller that steers sideways on its own: it drives at a fixed speed along
its route and, from `from_s`, steers to `offset_m` beside the route (left +), through a
yaw-rate command (heading error and lateral error fed back). Loaded by scenarios as
`weave:Weave` (the tests put this folder on sys.path)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from platoon_sumo.control import Command, Observation


@dataclass(frozen=True)
class WeaveParams:
    speed_mps: float = 10.0
    offset_m: float = 0.8
    from_s: float = 15.0
    heading_gain_1ps: float = 1.5
    offset_gain_1pms: float = 0.15


class Weave:
    Params: ClassVar[type[WeaveParams]] = WeaveParams

    def __init__(self, params: WeaveParams | None = None):
        self.params = params or WeaveParams()
        self._s_m: float | None = None

    def reset(self) -> None:
        self._s_m = None

    def step(self, observation: Observation) -> Command:
        p, obs = self.params, observation
        s_m, lateral_m = obs.path.project_sl(obs.x_m, obs.y_m, self._s_m, 20.0)
        self._s_m = s_m
        wanted_m = p.offset_m if obs.time_s >= p.from_s else 0.0
        error = obs.yaw_rad - obs.path.heading_at(s_m)
        error = math.atan2(math.sin(error), math.cos(error))
        yaw_rate = -p.heading_gain_1ps * error + p.offset_gain_1pms * (wanted_m - lateral_m)
        return Command(p.speed_mps, yaw_rate)
