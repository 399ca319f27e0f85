"""A user's own sensor, one module and no loop edit: a "perfect radar" that returns the
true bumper gap to the vehicle ahead on the route (SUMO's leader), and a controller that
keeps a gap with it. Loaded by scenarios as `perfect_radar:PerfectRadar` and
`perfect_radar:RadarFollower` (the tests put this folder on sys.path)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from platoon_sumo.control import Command, GapPolicy, Observation, Telemetry
from platoon_sumo.sensors.base import SensingBatch


@dataclass(frozen=True)
class RadarParams:
    range_max_m: float = 150.0
    rate_hz: float = 10.0


@dataclass(frozen=True)
class RadarReading:
    gap_m: float | None
    """Bumper-to-bumper gap to the vehicle ahead, None beyond range."""
    speed_mps: float | None
    """Its speed."""


class PerfectRadar:
    Params: ClassVar[type[RadarParams]] = RadarParams

    def __init__(self, params: RadarParams) -> None:
        self.params = params

    @property
    def period_s(self) -> float:
        return 1.0 / self.params.rate_hz

    def observe(self, batch: SensingBatch) -> list[RadarReading]:
        out = []
        for ahead in batch.vehicle_ahead:
            if ahead is None or ahead.gap_m > self.params.range_max_m:
                out.append(RadarReading(None, None))
            else:
                out.append(RadarReading(ahead.gap_m, ahead.speed_mps))
        return out


@dataclass(frozen=True)
class RadarFollowerParams:
    gap_m: float = 10.0
    gain: float = 0.5
    cruise_speed_mps: float = 12.0


class RadarFollower:
    """Keeps `gap_m` to the vehicle ahead with the radar; cruises without a reading."""

    Params: ClassVar[type[RadarFollowerParams]] = RadarFollowerParams

    def __init__(self, params: RadarFollowerParams | None = None) -> None:
        self.params = params or RadarFollowerParams()

    def reset(self) -> None:
        pass

    def step(self, observation: Observation) -> Command:
        p = self.params
        reading = observation.sensors.get("radar")
        if not isinstance(reading, RadarReading) or reading.gap_m is None:
            return Command(p.cruise_speed_mps)
        lead = reading.speed_mps or 0.0
        speed = max(0.0, min(p.cruise_speed_mps, lead + p.gain * (reading.gap_m - p.gap_m)))
        return Command(speed, telemetry=Telemetry("radar", reading.gap_m, GapPolicy(p.gap_m)))
