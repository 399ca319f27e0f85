"""Sensor models as plug-ins: the protocol, the registry and what a model is given.

A sensor model produces one message per equipped vehicle when its period has elapsed.
The loop batches every due vehicle whose sensor has the same model and parameters into
one `observe` call, so a model can work over all of them at once (the laser casts all
its scans in a few numpy calls). Messages reach the controller in
`Observation.sensors[name]` and hooks in the step record; a model never calls SUMO.

Adding a sensor is one module: a class with a frozen `Params` dataclass, `period_s` and
`observe`, registered with `@SENSORS.register("name")` (or named in a scenario as
`package.module:Class`); its parameters are checked like every other scenario key.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.registry import Registry
from platoon_sumo.world import VehicleAhead, WorldSnapshot

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class SensingBatch:
    """The vehicles due for one sensor model this step, and the world they sense.

    The world is the snapshot read after the previous SUMO step (what exists when the
    controllers decide); `footprints` are its vehicles' rectangles (centre x, centre y,
    yaw, length, width), ours from our exact state, in `world` order. `own_index` is each
    sensing vehicle's row in `footprints` (-1 if absent), to exclude itself."""

    time_s: float
    vehicle_ids: tuple[str, ...]
    front_x_m: FloatArray
    front_y_m: FloatArray
    yaw_rad: FloatArray
    speed_mps: FloatArray
    own_index: IntArray
    predecessor_index: IntArray
    """Row in `footprints` of each vehicle's platoon predecessor (-1: none), for ground
    truth labels only (a sensor model must not use it to decide what it measures)."""
    vehicle_ahead: tuple[VehicleAhead | None, ...]
    """SUMO's leader on each vehicle's route lanes (ground truth)."""
    world: WorldSnapshot
    footprints: FloatArray
    static_segments: FloatArray | None
    rng: np.random.Generator
    platoon_ids: tuple[str, ...] = ()
    """Each vehicle's platoon."""
    member_index: IntArray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    """Each vehicle's position in its platoon (0 = leader)."""
    accel_mps2: FloatArray = field(default_factory=lambda: np.empty(0))
    """Each vehicle's acceleration over the last step."""
    desired_accel_mps2: FloatArray = field(default_factory=lambda: np.empty(0))
    """The acceleration each vehicle's last command asked for (its controller's
    `Telemetry.desired_accel_mps2`, or the commanded speed change within its limits):
    what a V2V channel broadcasts."""


class SensorModel(Protocol):
    """One kind of sensor with one set of parameters, observing batches of vehicles."""

    Params: ClassVar[type[Any]]

    def __init__(self, params: Any) -> None: ...

    @property
    def period_s(self) -> float:
        """Time between two messages of one vehicle [s]; 0: every step."""
        ...

    def observe(self, batch: SensingBatch) -> Sequence[Any]:
        """One message per vehicle of the batch, in its order."""
        ...


def check_sensor(cls: object) -> str | None:
    """Why `cls` cannot be a sensor model (None when it can)."""
    params = getattr(cls, "Params", None)
    if (
        isinstance(params, type)
        and dataclasses.is_dataclass(params)
        and callable(getattr(cls, "observe", None))
        and hasattr(cls, "period_s")
    ):
        return None
    return "needs a Params dataclass, a period_s property and observe()"


SENSORS: Registry[type[SensorModel]] = Registry("sensor", check_sensor)
