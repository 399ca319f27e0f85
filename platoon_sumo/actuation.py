"""How commands reach SUMO: actuation modes as plug-ins (`platoons[].actuation`).

An actuator gets one platoon's executed commands as arrays and moves its vehicles for
the next SUMO step. Two are built in:

- `planar`: our vehicle model integrates speed and yaw rate and the pose is placed into
  SUMO (`moveToXY` + `setPreviousSpeed`): free lateral motion, our own lane changes.
- `lane`: SUMO drives the vehicle along its lanes at the commanded speed (`setSpeed`),
  with its safe speed, lights and right of way underneath, and makes lane changes the
  controller asks for; the pose SUMO produced is read back after the step.

A new mode is one module: a class with `sumo_drives` and `apply`, registered with
`@ACTUATORS.register("name")`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.registry import Registry
from platoon_sumo.vehicles import KinematicState, MotionLimits, VehicleModel

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class ActuationPort(Protocol):
    """The part of the SUMO backend an actuator may use."""

    def move(
        self,
        vehicle_ids: Sequence[str],
        front_x_m: FloatArray,
        front_y_m: FloatArray,
        yaw_rad: FloatArray,
        speed_mps: FloatArray,
    ) -> dict[str, str]: ...

    def set_speeds(self, vehicle_ids: Sequence[str], speed_mps: FloatArray) -> None: ...

    def request_lane_changes(self, requests: dict[str, int]) -> None: ...

    def set_lateral_speeds(self, vehicle_ids: Sequence[str], speed_mps: FloatArray) -> None: ...


@dataclass(frozen=True)
class ActuationBatch:
    """One platoon's vehicles (they share a model and limits) and their executed
    commands. The state is the model's reference point (rear axle / wheel axle)."""

    vehicle_ids: tuple[str, ...]
    state: KinematicState
    speed_cmd_mps: FloatArray
    yaw_rate_cmd_radps: FloatArray
    lane_change: IntArray
    road_heading_rad: FloatArray
    """Direction of the route path at each vehicle's middle (sideways is across it)."""
    front_offset_m: float
    limits: MotionLimits
    model: VehicleModel
    dt_s: float


@dataclass(frozen=True)
class ActuationResult:
    state: KinematicState | None
    """The state after the step, or None where SUMO moves the vehicles (read back)."""
    failed: dict[str, str]
    """Vehicles SUMO could not place, with its reason (taken out of the run)."""


class Actuator(Protocol):
    sumo_drives: ClassVar[bool]
    """SUMO moves the vehicles along their lanes (their state is read back after each
    step); False: we place them (SUMO neither brakes nor steers them)."""
    steers: ClassVar[bool]
    """The controllers' heading commands move the vehicles sideways (planar, sublane);
    False: SUMO keeps them on lane centres and makes the lane changes (lane)."""

    def apply(self, batch: ActuationBatch, sumo: ActuationPort) -> ActuationResult: ...


def check_actuator(cls: object) -> str | None:
    if (
        isinstance(getattr(cls, "sumo_drives", None), bool)
        and isinstance(getattr(cls, "steers", None), bool)
        and callable(getattr(cls, "apply", None))
    ):
        return None
    return "needs booleans sumo_drives and steers, and apply()"


ACTUATORS: Registry[type[Actuator]] = Registry("actuation", check_actuator)


@ACTUATORS.register("planar")
class PlanarActuation:
    sumo_drives: ClassVar[bool] = False
    steers: ClassVar[bool] = True

    def apply(self, batch: ActuationBatch, sumo: ActuationPort) -> ActuationResult:
        new = batch.model.step(
            batch.state, batch.speed_cmd_mps, batch.yaw_rate_cmd_radps, batch.limits, batch.dt_s
        )
        c, s = np.cos(new.yaw_rad), np.sin(new.yaw_rad)
        failed = sumo.move(
            batch.vehicle_ids,
            new.x_m + batch.front_offset_m * c,
            new.y_m + batch.front_offset_m * s,
            new.yaw_rad,
            new.speed_mps,
        )
        return ActuationResult(new, failed)


@ACTUATORS.register("lane")
class LaneActuation:
    sumo_drives: ClassVar[bool] = True
    steers: ClassVar[bool] = False

    def apply(self, batch: ActuationBatch, sumo: ActuationPort) -> ActuationResult:
        sumo.set_speeds(batch.vehicle_ids, batch.speed_cmd_mps)
        requests = {
            vid: int(lane)
            for vid, lane in zip(batch.vehicle_ids, batch.lane_change, strict=True)
            if lane
        }
        if requests:
            sumo.request_lane_changes(requests)
        return ActuationResult(None, {})


@ACTUATORS.register("sublane")
class SublaneActuation:
    sumo_drives: ClassVar[bool] = True
    steers: ClassVar[bool] = True

    def apply(self, batch: ActuationBatch, sumo: ActuationPort) -> ActuationResult:
        """The speed command to SUMO; sideways, the speed across the road that the
        vehicle model predicts for this step from the commanded speed and yaw rate."""
        sumo.set_speeds(batch.vehicle_ids, batch.speed_cmd_mps)
        new = batch.model.step(
            batch.state, batch.speed_cmd_mps, batch.yaw_rate_cmd_radps, batch.limits, batch.dt_s
        )
        heading = batch.road_heading_rad
        dx, dy = new.x_m - batch.state.x_m, new.y_m - batch.state.y_m
        lateral_mps = (dy * np.cos(heading) - dx * np.sin(heading)) / batch.dt_s
        sumo.set_lateral_speeds(batch.vehicle_ids, lateral_mps)
        return ActuationResult(None, {})
