"""A test controller that ignores its route's lane change for a while: it drives at a
fixed speed and keeps the y coordinate it started at, or `hold_y_m` (for roads along +x),
until its front bumper has come `hold_until_s` along its route, then steers onto the route path
(heading and offset fed back, as `weave.Weave`). Loaded by scenarios as
`hold_lane:HoldLane` (the tests put this folder on sys.path)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from platoon_sumo.control import Command, Observation


@dataclass(frozen=True)
class HoldLaneParams:
    speed_mps: float = 8.0
    hold_until_s: float = 1000.0
    hold_y_m: float | None = None
    heading_gain_1ps: float = 1.5
    offset_gain_1pms: float = 0.15


class HoldLane:
    Params: ClassVar[type[HoldLaneParams]] = HoldLaneParams

    def __init__(self, params: HoldLaneParams | None = None):
        self.params = params or HoldLaneParams()
        self._s_m: float | None = None
        self._y0_m: float | None = None

    def reset(self) -> None:
        self._s_m = self._y0_m = None

    def step(self, observation: Observation) -> Command:
        p, obs = self.params, observation
        s_m, lateral_m = obs.path.project_sl(obs.x_m, obs.y_m, self._s_m, 20.0)
        self._s_m = s_m
        if self._y0_m is None:
            self._y0_m = obs.y_m if p.hold_y_m is None else p.hold_y_m
        front_s_m = s_m + obs.front_offset_m
        wanted_m = 0.0
        if front_s_m < p.hold_until_s:  # the start's y, as an offset from the path
            wanted_m = self._y0_m - obs.path.point_at(s_m)[1]
        error = obs.yaw_rad - obs.path.heading_at(s_m)
        error = math.atan2(math.sin(error), math.cos(error))
        yaw_rate = -p.heading_gain_1ps * error + p.offset_gain_1pms * (wanted_m - lateral_m)
        return Command(p.speed_mps, yaw_rate)
