"""A user's own controller, loaded by scenario files as `my_controller:MyController`.

Only importable when the tests put this folder on sys.path (see test_scenario_errors.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from platoon_sumo.config_loader import require
from platoon_sumo.control import Command, Observation


@dataclass(frozen=True)
class MyParams:
    gain: float = 1.0
    """Proportional gain (must be > 0)."""
    cruise_speed_mps: float = 5.0

    def __post_init__(self) -> None:
        require(self.gain > 0, "gain", "must be > 0")


class MyController:
    """Drives at a constant speed; enough to be a valid controller."""

    Params: ClassVar[type[MyParams]] = MyParams

    def __init__(self, params: MyParams | None = None) -> None:
        self.params = params or MyParams()

    def reset(self) -> None:
        pass

    def step(self, observation: Observation) -> Command:
        return Command(speed_mps=self.params.cruise_speed_mps)


class NotAController:
    """Importable, but has no Params, reset() or step()."""


class ParamsNotADataclass:
    """Looks like a controller, but its Params is a plain class, not a dataclass."""

    class Params:
        gain = 1.0

    def __init__(self, params: object = None) -> None:
        self.params = params

    def reset(self) -> None:
        pass

    def step(self, observation: Observation) -> Command:
        return Command(speed_mps=0.0)
