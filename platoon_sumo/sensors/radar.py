"""An automotive front radar ("radar"): the gap to the vehicle ahead and its speed.

Ground truth from SUMO's leader on the vehicle's route lanes (`SensingBatch.vehicle_ahead`),
cut at the radar's range, with optional Gaussian noise. It is the range sensor of the
`acc` and `cacc` baselines, the sensing an ACC car has; the laser follower does not use it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from platoon_sumo.config_loader import bounded
from platoon_sumo.sensors.base import SENSORS, SensingBatch


@dataclass(frozen=True)
class RadarParams:
    range_max_m: float = bounded(150.0, gt=0, le=1000)
    """Farthest gap measured [m]; beyond it the reading is empty."""
    rate_hz: float = bounded(20.0, gt=0, le=1000)
    """Measurements per second."""
    gap_noise_m: float = bounded(0.0, ge=0, le=10)
    """Standard deviation of the gap's Gaussian noise [m]."""
    speed_noise_mps: float = bounded(0.0, ge=0, le=10)
    """Standard deviation of the target speed's Gaussian noise [m/s]."""


@dataclass(frozen=True)
class RadarReading:
    time_s: float
    gap_m: float | None
    """Own front bumper to the target's rear bumper [m]; None: nothing within range."""
    speed_mps: float | None
    """The target's speed [m/s]."""
    target_id: str | None
    """Ground truth identity of the target (a real system associates radar targets with
    V2V senders by position; the baselines use it for that association)."""


@SENSORS.register("radar")
class Radar:
    Params: ClassVar[type[RadarParams]] = RadarParams

    def __init__(self, params: RadarParams) -> None:
        self.params = params

    @property
    def period_s(self) -> float:
        return 1.0 / self.params.rate_hz

    def observe(self, batch: SensingBatch) -> list[RadarReading]:
        p = self.params
        # two draws per vehicle whatever it sees, so the random stream does not depend
        # on the traffic
        noise = batch.rng.standard_normal((len(batch.vehicle_ids), 2))
        out = []
        for ahead, (gap_noise, speed_noise) in zip(
            batch.vehicle_ahead, noise.tolist(), strict=True
        ):
            if ahead is None or ahead.gap_m > p.range_max_m:
                out.append(RadarReading(batch.time_s, None, None, None))
                continue
            gap = max(ahead.gap_m + p.gap_noise_m * gap_noise, 0.0)
            speed = max(ahead.speed_mps + p.speed_noise_mps * speed_noise, 0.0)
            out.append(RadarReading(batch.time_s, gap, speed, ahead.vehicle_id))
        return out
