"""`sumo_driver`: a member whose speed SUMO's own car-following model decides.

A baseline inside any scenario: SUMO's Krauss, IDM, ACC, CACC (any model SUMO's vehicle
type schema lists) drives the member, while the loop records it like every other member
(trajectories, gap to the predecessor, events, metrics) and it stays in its platoon. It
needs `actuation: lane`: SUMO keeps the lane and makes the route's lane changes.

How: the controller declares the model (`sumo_car_following`); the member gets a vehicle
type of its own, `platoon_<id>_<role>`, with that `carFollowModel` and its attributes
(libsumo cannot set a type's model, so the type comes from an additional file written
at the start of the run), and each step its speed is handed back to SUMO
(`setSpeed(-1)`). The command returned here is never sent: it asks for the speed the
member drives now, so the supervisor, which runs on every member, only checks it (its
state marks the steps where its bounds lay below the speed SUMO's model held, e.g.
`emergency` close behind the vehicle ahead, and no emergency braking is reported, since
nothing brakes); SUMO's own safe speed, lights and
right of way drive the member, as for its other cars. The vehicle's powertrain
(`actuator_lag_s`, `max_jerk_mps3`) does not apply: SUMO's models have none.

SUMO's models declare no spacing policy the loop could measure against (IDM's
equilibrium gap is not `s0 + v T`), so no spacing error is recorded; the measured gap is
SUMO's leader's.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

from platoon_sumo.config_loader import FieldError, bounded, require_choice
from platoon_sumo.control.base import (
    CONTROLLERS,
    Command,
    Observation,
    SumoCarFollowing,
    Telemetry,
)
from platoon_sumo.errors import did_you_mean

#: vType attributes a model's table in SUMO's schema lists that come from elsewhere:
#: tau from `tau_s`, the limits from the platoon's vehicle, and no driver imperfection.
_SET_ELSEWHERE = {
    "tau": "tau_s",
    "accel": "the platoon's vehicle.max_accel_mps2",
    "decel": "the platoon's vehicle.max_decel_mps2",
    "emergencyDecel": "the platoon's vehicle.max_decel_mps2",
    "sigma": "nothing: members drive without driver imperfection",
}
_XSD_NS = "{http://www.w3.org/2001/XMLSchema}"


@functools.cache
def sumo_models() -> dict[str, tuple[str, ...]]:
    """SUMO's car-following models and each one's attributes, as the vehicle-type schema
    of the installed SUMO lists them (`data/xsd/types/route.xsd`): the authority on
    names, so a misspelt model or parameter is caught before SUMO starts."""
    import sumo  # the eclipse-sumo wheel's location only (no libsumo)

    schema = ET.parse(Path(sumo.SUMO_HOME) / "data" / "xsd" / "types" / "route.xsd").getroot()
    types = {
        t.get("name"): tuple(a.get("name", "") for a in t.iter(f"{_XSD_NS}attribute"))
        for t in schema.iter(f"{_XSD_NS}complexType")
    }
    prefix = "carFollowing-"
    return {
        str(e.get("name"))[len(prefix) :]: types.get(e.get("type"), ())
        for e in schema.iter(f"{_XSD_NS}element")
        if str(e.get("name", "")).startswith(prefix)
    }


@dataclass(frozen=True)
class SumoDriverParams:
    """SUMO's car-following model for the member and the model's parameters."""

    car_follow_model: str = "IDM"
    """SUMO's `carFollowModel`: any model SUMO's vehicle-type schema lists, e.g. Krauss,
    IDM, EIDM, ACC, CACC, W99, Wiedemann."""
    tau_s: float = bounded(1.0, gt=0, le=100)
    """The model's `tau` [s]: IDM's time gap T, ACC's and CACC's desired time gap,
    Krauss's reaction time."""
    min_gap_m: float | None = bounded(None, ge=0, le=100)
    """The model's standstill gap, SUMO's `minGap` (IDM's s0) [m]; null: the platoon
    vehicle's `min_gap_m`."""
    parameters: Mapping[str, float] = field(default_factory=dict)
    """Further attributes of the model by SUMO's names, as its schema lists them for the
    model (e.g. IDM's `delta`, CACC's `speedControlGainCACC`); SUMO's defaults otherwise.
    The acceleration limits are the vehicle's, and sigma is 0."""

    def __post_init__(self) -> None:
        models = sumo_models()
        require_choice(self.car_follow_model, sorted(models), "car_follow_model")
        allowed = [a for a in models[self.car_follow_model] if a not in _SET_ELSEWHERE]
        for name in self.parameters:
            if name in _SET_ELSEWHERE:
                raise FieldError(
                    f"parameters.{name}",
                    f"is not a parameter here: it comes from {_SET_ELSEWHERE[name]}",
                )
            if name not in allowed:
                raise FieldError(
                    f"parameters.{name}",
                    f"SUMO's {self.car_follow_model} has no attribute '{name}' "
                    f"(its attributes: {', '.join(allowed) or 'none besides tau'})",
                    did_you_mean(name, allowed),
                )


@CONTROLLERS.register("sumo_driver")
class SumoDriver:
    """SUMO's car-following model drives the member's speed; the command only asks for
    the speed it drives now (the supervisor's check)."""

    Params: ClassVar[type[SumoDriverParams]] = SumoDriverParams
    reads_link_ahead: ClassVar[bool] = False

    def __init__(self, params: SumoDriverParams) -> None:
        self.params = params
        self._mode = f"sumo_{params.car_follow_model}"

    @staticmethod
    def sumo_car_following(params: SumoDriverParams) -> SumoCarFollowing:
        return SumoCarFollowing(
            params.car_follow_model,
            params.tau_s,
            params.min_gap_m,
            {name: repr(float(value)) for name, value in params.parameters.items()},
        )

    def reset(self) -> None:
        """Nothing to forget: SUMO holds the model's state."""

    def step(self, observation: Observation) -> Command:
        ahead = observation.vehicle_ahead
        gap = ahead.gap_m if ahead is not None else None
        return Command(
            observation.speed_mps, telemetry=Telemetry(mode=self._mode, measured_gap_m=gap)
        )
