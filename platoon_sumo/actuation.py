"""How commands reach SUMO: actuation modes as plug-ins (`platoons[].actuation`).

An actuator gets the executed commands of a group of platoons that share the mode,
vehicle, limits and model (`loop.actuate.Actuate`; usually the whole fleet) as arrays
and moves their vehicles for the next SUMO step; state an actuator keeps between steps
is per vehicle id (the group's first member's instance is called). Three are built in:

- `planar`: our vehicle model integrates speed and yaw rate and the pose is placed into
  SUMO (`moveToXY` + `setPreviousSpeed`): free lateral motion, our own lane changes.
- `lane`: SUMO drives the vehicle along its lanes at the commanded speed (`setSpeed`),
  with its safe speed, lights and right of way underneath, and makes lane changes the
  controller asks for; the pose SUMO produced is read back after the step.
- `sublane`: SUMO drives the speed as in `lane`; the controller's yaw rate becomes a
  lateral speed in SUMO's sublane model (`changeSublane`), checked against the cars
  beside; the pose is read back.

A new mode is one module: a class with `sumo_drives`, `steers` and `apply`, registered with
`@ACTUATORS.register("name")`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.fault import PLACED_REACTION_S
from platoon_sumo.geometry import wrap_angle
from platoon_sumo.kernels.sideways import landing_conflicts, sideways_conflicts
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

    def body_directions(
        self, vehicle_ids: Sequence[str], ahead_m: FloatArray
    ) -> tuple[FloatArray, FloatArray]: ...

    def in_junctions(self, vehicle_ids: Sequence[str]) -> NDArray[np.bool_]: ...

    def lane_room(
        self, vehicle_ids: Sequence[str]
    ) -> tuple[FloatArray, FloatArray, FloatArray]: ...

    def bends_ahead(self, vehicle_ids: Sequence[str]) -> tuple[FloatArray, FloatArray]: ...

    def sumo_lateral_speeds(
        self, vehicle_ids: Sequence[str], offset_m: FloatArray
    ) -> FloatArray: ...

    def lane_change_landings(
        self,
        vehicle_ids: Sequence[str],
        offset_m: FloatArray,
        lateral_mps: FloatArray,
        speed_mps: FloatArray,
        dt_s: float,
    ) -> FloatArray: ...

    def hold_lateral(self, vehicle_ids: Sequence[str]) -> None: ...


@dataclass(frozen=True)
class ActuationBatch:
    """Vehicles of one or more platoons that share a model, limits and vehicle, and
    their executed commands. The state is the model's reference point (rear axle /
    wheel axle)."""

    vehicle_ids: tuple[str, ...]
    state: KinematicState
    speed_cmd_mps: FloatArray
    yaw_rate_cmd_radps: FloatArray
    lane_change: IntArray
    front_offset_m: float
    length_m: float
    limits: MotionLimits
    model: VehicleModel
    dt_s: float
    keep_lane: NDArray[np.bool_] | None = None
    """Per vehicle: hold the current lane (`Command.keep_lane`); None: no one asks."""
    sidestep_m: FloatArray | None = None
    """Per vehicle: the sideways shift (left +) that clears a standing car reaching into
    its way, one of the two in a junction (`ObstaclesAhead`); 0: none. None: no one
    has one."""
    surroundings: Surroundings | None = None
    """Every vehicle's footprint, to keep sideways moves off the cars beside. This and
    `sidestep_m` are given to actuators that steer only."""


@dataclass(frozen=True)
class Surroundings:
    """Every vehicle in the network after the last step: (N, 5) rectangles (centre,
    yaw, length, width; `platoon_sumo.geometry`), speeds and yaw rates over the last
    step, and the batch's rows in them (-1: not in the network)."""

    footprints: FloatArray
    speed_mps: FloatArray
    yaw_rate_radps: FloatArray
    rows: IntArray


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
        keep = batch.keep_lane
        if keep is None:
            keep = np.zeros(len(batch.vehicle_ids), dtype=bool)
        requests = {
            vid: int(lane)  # 0: keep the lane
            for vid, lane, hold in zip(batch.vehicle_ids, batch.lane_change, keep, strict=True)
            if lane or hold
        }
        if requests:
            sumo.request_lane_changes(requests)
        return ActuationResult(None, {})


#: Sublane actuation: the heading asked for is kept within this angle of the lane
#: [rad] (the lateral speed grows with its tangent).
MAX_LANE_ANGLE_RAD = math.radians(60.0)
#: Sublane actuation: a sideways move is checked against the cars around over this
#: horizon [s] with this clearance [m] (`sideways_conflicts`).
SIDEWAYS_HORIZON_S, SIDEWAYS_CLEARANCE_M = 0.5, 0.2
#: Sublane actuation: a sidestep (`ActuationBatch.sidestep_m`) runs at most this fast [m/s].
SIDESTEP_SPEED_MPS = 0.5
#: Sublane actuation: this long [s] before the end of its lane or a sharp bend (as fast
#: as it could get there) a car's sideways move is bounded so that it gets there within
#: the room it has there (`fit_ahead`), moving back at up to `FIT_LATERAL_MPS` [m/s]
#: (SUMO's default `maxSpeedLat`) or as fast as the controller asked, starting earlier
#: when it needs longer, plus `FIT_RAMP_S` [s] (SUMO's lateral speed grows at its
#: default `lcAccelLat` of 1 m/s^2).
FIT_AHEAD_S, FIT_LATERAL_MPS, FIT_RAMP_S = 3.0, 1.0, 1.0


@ACTUATORS.register("sublane")
class SublaneActuation:
    sumo_drives: ClassVar[bool] = True
    steers: ClassVar[bool] = True

    def apply(self, batch: ActuationBatch, sumo: ActuationPort) -> ActuationResult:
        """The speed command to SUMO; sideways, the lateral speed that turns SUMO's
        vehicle to the heading our vehicle model reaches at the end of the step.

        SUMO moves the front bumper along its lane at speed v and across it at the
        lateral speed u asked for; the vehicle's angle is the direction from its back
        to its front along the lanes (the body direction `sumo.body_directions`) turned
        by an angle a that follows u as a body dragged by its front:
        a' = a + asin(cos(a) (u - v tan(a)) dt / length). Solved for u, with a the angle
        read back now and a' the one wanted after the step (the model's heading minus
        the body direction there):
        u = v tan(a) + length sin(a' - a) / (cos(a) dt).

        Everything is in SUMO's frame, not the route path's: where the path crosses lanes
        (a lane-change stretch) its direction is up to 10 degrees off the lanes', and a
        lateral speed measured across the path fed that difference back every step (cars
        asked to follow a blend to the left were driven two lanes to the right). v is the
        speed SUMO drove (the state read back), not the command: where SUMO held a car
        below the command, the ratio of the two multiplied the lateral speed every step.
        Without the second term SUMO's angle lags the lateral motion by length / v
        (0.6 s at 8 m/s), and the controllers overshot lane changes by a metre.

        While any part of a vehicle is on a junction's internal lane its lateral offset
        is held (SUMO's lane steers it through, as its own cars): those lanes bend
        tighter than a car can turn (1.6 m radius for a right turn on netgenerate's
        grids, 3.9 m the bicycle's rear axle), and the controllers steer the rear axle,
        which SUMO's body (front on the lane, back along the chord) puts inside the
        turn. The heading that lagged the lane's, turned into lateral speed, carried
        cars 2 m wide out of the junction into the next lane. A sidestep
        (`batch.sidestep_m`) goes before both: a car standing in or at a junction with
        its corner in the member's way, which would otherwise wait for a car that
        waits for it.

        Near the end of its lane (`FIT_AHEAD_S`) and inside a junction, the offset
        is bounded so that the body is inside the lane and the lanes after it when the
        car gets there (`fit_ahead`): SUMO lets a car onto the next lane only so,
        and holds it at the junction's exit otherwise, in the way of the cars beside.
        Before each of the next sharp bends of its lane's shape the offset is bounded
        the same way, to where SUMO does not jump the car along the road there
        (`sumo.bends_ahead`).

        No sideways move goes into a car beside: one that would bring the vehicle,
        `SIDEWAYS_CLEARANCE_M` larger, deeper into another at any step within
        `SIDEWAYS_HORIZON_S` (every car driving on at its speed and the yaw rate it
        showed over the last step: on a curve along it) is not made (the lateral speed
        is 0; SUMO's drivers let our commands through as they come and do not check
        them); nor is SUMO's own move of a car handed over to its lane change
        (`sumo.hold_lateral`). Neither is a lane change that SUMO would put down onto
        another car, away from where the car drives (`_jumps_into_others`)."""
        sumo.set_speeds(batch.vehicle_ids, batch.speed_cmd_mps)
        speed = np.maximum(batch.state.speed_mps, 0.0)
        new = batch.model.step(
            batch.state, speed, batch.yaw_rate_cmd_radps, batch.limits, batch.dt_s
        )
        body_now, body_next = sumo.body_directions(batch.vehicle_ids, speed * batch.dt_s)
        limit = MAX_LANE_ANGLE_RAD
        angle = np.clip(wrap_angle(batch.state.yaw_rad - body_now), -limit, limit)
        wanted = np.clip(wrap_angle(new.yaw_rad - body_next), -limit, limit)
        lateral = speed * np.tan(angle) + batch.length_m * np.sin(wanted - angle) / (
            np.cos(angle) * batch.dt_s
        )
        # in a junction SUMO's lane steers: the lateral offset is held, or sidesteps
        lateral[sumo.in_junctions(batch.vehicle_ids)] = 0.0
        if batch.sidestep_m is not None:
            side = batch.sidestep_m != 0.0
            step = batch.sidestep_m[side] / batch.dt_s
            lateral[side] = np.clip(step, -SIDESTEP_SPEED_MPS, SIDESTEP_SPEED_MPS)
        offset, room, to_end = sumo.lane_room(batch.vehicle_ids)
        lateral = fit_ahead(lateral, offset, room, to_end, speed, 0.0, batch.dt_s)
        rooms, to_bends = sumo.bends_ahead(batch.vehicle_ids)
        accel = batch.limits.max_accel_mps2
        for room, to_bend in zip(rooms.T, to_bends.T, strict=True):
            lateral = fit_ahead(lateral, offset, room, to_bend, speed, accel, batch.dt_s)
        around = batch.surroundings
        held: list[str] = []
        if around is not None:
            # SUMO moves the cars handed over to it (`lateral` is ours for the others)
            theirs = sumo.sumo_lateral_speeds(batch.vehicle_ids, offset)
            sumos = ~np.isnan(theirs)
            moving = np.where(sumos, theirs, lateral)
            blocked = sideways_conflicts(
                around.footprints, around.speed_mps, around.yaw_rate_radps, around.rows,
                moving * SIDEWAYS_HORIZON_S, SIDEWAYS_HORIZON_S, SIDEWAYS_CLEARANCE_M,
                batch.dt_s,
            )  # fmt: skip
            blocked |= _jumps_into_others(sumo, batch, around, offset, moving, speed)
            lateral[blocked] = 0.0
            held = [batch.vehicle_ids[k] for k in np.flatnonzero(blocked & sumos).tolist()]
        sumo.set_lateral_speeds(batch.vehicle_ids, lateral)
        if held:
            sumo.hold_lateral(held)
        return ActuationResult(None, {})


def _jumps_into_others(
    sumo: ActuationPort,
    batch: ActuationBatch,
    around: Surroundings,
    offset_m: FloatArray,
    lateral_mps: FloatArray,
    speed_mps: FloatArray,
) -> NDArray[np.bool_]:
    """Per car: would SUMO put its lane change in this step down away from where it
    drives (`lane_change_landings`), into another car or within its reach (both driving
    on for `PLACED_REACTION_S`, `SIDEWAYS_CLEARANCE_M` apart)? Such a sideways move
    waits. Where the landing is clear the jump is left to SUMO: a rule that held every
    such change stranded platoons on a ramp whose lanes lie apart along its length."""
    lim, dt = batch.limits, batch.dt_s
    reached = np.clip(
        batch.speed_cmd_mps,
        np.maximum(speed_mps - lim.max_decel_mps2 * dt, 0.0),
        speed_mps + lim.max_accel_mps2 * dt,
    )
    landings = sumo.lane_change_landings(batch.vehicle_ids, offset_m, lateral_mps, reached, dt)
    out = np.zeros(len(batch.vehicle_ids), dtype=np.bool_)
    jumping = np.flatnonzero(~np.isnan(landings[:, 0]))
    if len(jumping):
        out[jumping] = landing_conflicts(
            around.footprints, around.speed_mps, around.yaw_rate_radps, around.rows[jumping],
            landings[jumping], reached[jumping], PLACED_REACTION_S, SIDEWAYS_CLEARANCE_M, dt,
        )  # fmt: skip
    return out


def fit_ahead(
    lateral_mps: FloatArray,
    offset_m: FloatArray,
    room_m: FloatArray,
    to_m: FloatArray,
    speed_mps: FloatArray,
    accel_mps2: float,
    dt_s: float,
) -> FloatArray:
    """The lateral speeds (left +) bounded so that a car reaching a point `to_m` ahead
    (its lane's end, a sharp bend of its lane) soon gets there with its offset within
    `room_m` of the lane's centre (held there once inside; moved back at up to
    `FIT_LATERAL_MPS`, or the speed asked for if faster, from outside). Soon is within
    `FIT_AHEAD_S`, or the time moving back takes, with `FIT_RAMP_S` for SUMO to reach
    that lateral speed, if longer; the time to get there is the shortest the car can
    take speeding up at `accel_mps2` (a bend: a car standing before it may drive off
    onto it), or at its speed with 0 (a lane's end: SUMO holds a car there until it
    fits). A car at the point counts as arriving within one step: it moves back into
    the room it needs to go on."""
    v, to, a = np.maximum(speed_mps, 0.0), np.minimum(to_m, 1e9), accel_mps2  # 1e9: no point
    if a > 0.0:
        left_s = np.maximum((np.sqrt(v * v + 2.0 * a * to) - v) / a, dt_s)  # v t + a t^2 / 2
    else:
        left_s = np.maximum(to / np.maximum(v, 1e-3), dt_s)
    back_s = (np.abs(offset_m) - room_m) / FIT_LATERAL_MPS + FIT_RAMP_S
    near = left_s <= np.maximum(back_s, FIT_AHEAD_S)
    out = np.array(lateral_mps, dtype=np.float64)
    if near.any():
        asked, offset, room, left = out[near], offset_m[near], room_m[near], left_s[near]
        fitted = np.clip(asked, (-room - offset) / left, (room - offset) / left)
        cap = np.maximum(np.abs(asked), FIT_LATERAL_MPS)
        out[near] = np.clip(fitted, -cap, cap)
    return out
