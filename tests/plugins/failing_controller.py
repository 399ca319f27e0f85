"""A user's controller with a bug that shows only in the middle of a run.

Loaded as `failing_controller:FailsAt` when the tests put this folder on sys.path.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from platoon_sumo.control import Command, Observation


@dataclass(frozen=True)
class FailsAtParams:
    fail_at_s: float = 3.0
    """First simulated time [s] at which `step` raises."""
    speed_mps: float = 5.0


class FailsAt:
    """Drives at a constant speed, then divides by zero at `fail_at_s`."""

    Params: ClassVar[type[FailsAtParams]] = FailsAtParams

    def __init__(self, params: FailsAtParams | None = None) -> None:
        self.params = params or FailsAtParams()

    def reset(self) -> None:
        pass

    def step(self, observation: Observation) -> Command:
        if observation.time_s >= self.params.fail_at_s - 1e-9:
            return Command(1.0 / 0.0)
        return Command(self.params.speed_mps)
