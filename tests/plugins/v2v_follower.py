"""A follower that keeps its gap with V2V alone: the gap from its predecessor's latest
beacon (front bumpers, and its own length for the predecessor's: one vehicle type per
platoon), the predecessor's speed plus a gap term. Every step's view is kept in the
class attribute `seen` for the tests. Loaded by scenarios as `v2v_follower:V2VFollower`
(the tests put this folder on sys.path)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from platoon_sumo.control import Command, GapPolicy, Observation, Telemetry
from platoon_sumo.sensors.v2v import V2VInbox, V2VMessage


@dataclass(frozen=True)
class V2VFollowerParams:
    gap_m: float = 10.0
    gain_1ps: float = 0.5
    channel: str = "v2v"
    """Name of the V2V sensor in the observation."""


@dataclass(frozen=True)
class Seen:
    vehicle_id: str
    time_s: float
    inbox: V2VInbox | None
    predecessor: V2VMessage | None


class V2VFollower:
    Params: ClassVar[type[V2VFollowerParams]] = V2VFollowerParams
    seen: ClassVar[list[Seen]] = []

    def __init__(self, params: V2VFollowerParams | None = None) -> None:
        self.params = params or V2VFollowerParams()

    def reset(self) -> None:
        pass

    def step(self, observation: Observation) -> Command:
        p, obs = self.params, observation
        inbox = obs.sensors.get(p.channel)
        inbox = inbox if isinstance(inbox, V2VInbox) else None
        ahead = inbox.from_member(obs.platoon_id, obs.index - 1) if inbox else None
        V2VFollower.seen.append(Seen(obs.vehicle_id, obs.time_s, inbox, ahead))
        if ahead is None:
            return Command(0.0)
        front_x = obs.x_m + obs.front_offset_m * math.cos(obs.yaw_rad)
        front_y = obs.y_m + obs.front_offset_m * math.sin(obs.yaw_rad)
        gap = math.hypot(ahead.front_x_m - front_x, ahead.front_y_m - front_y) - obs.length_m
        speed = max(0.0, ahead.speed_mps + p.gain_1ps * (gap - p.gap_m))
        return Command(speed, telemetry=Telemetry("v2v", gap, GapPolicy(p.gap_m)))
