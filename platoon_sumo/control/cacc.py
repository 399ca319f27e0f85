"""Communication and radar baselines: `acc` and `cacc` (Ploeg et al. 2011).

Both keep a constant time gap to the vehicle ahead measured by a range sensor (the
`radar` sensor by default) with the controller of Ploeg, Scheepers, van Nunen, van de
Wouw and Nijmeijer, "Design and experimental evaluation of cooperative adaptive cruise
control" (ITSC 2011):

    e  = gap - (standstill_gap + h v)                 spacing error
    e' = v_ahead - v - h a                            its rate
    u' = (-u + kp e + kd e' + u_ff) / h               desired acceleration

`cacc` feeds forward `u_ff`, the desired acceleration its predecessor broadcast over the
V2V channel (`v2v` sensor); `acc` is the same law with `u_ff = 0`, the classic radar-only
ACC, which needs a much larger time gap to damp disturbances along a platoon. Without a
fresh message from the predecessor (older than `message_timeout_s`, or the radar's target
is another vehicle, e.g. after a cut-in) `cacc` falls back to `acc`: the feed-forward is
dropped and the time gap moves to `fallback_time_gap_s` at `time_gap_rate` seconds per
second (a step to the larger gap would brake hard), and back once messages return
(Ploeg et al. 2015 degrade to an estimated acceleration instead; here plainly to ACC).

The law sets the desired acceleration; the command is the speed it reaches within one
step, capped by route following's speed (speed limits, curves, signals), which also
steers. With nothing within the radar's range the vehicle cruises as route following.
That frame (`GapControl`), the message check (`fresh_message`) and the time gap's ramp
(`ramp`) serve `path_cacc` too (path_cacc.py), whose fall-back is this ACC law.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

from platoon_sumo.config_loader import bounded, require_positive
from platoon_sumo.control.base import CONTROLLERS, Command, GapPolicy, Observation, Telemetry
from platoon_sumo.control.route_following import RouteFollowing, RouteFollowingParams
from platoon_sumo.sensors.radar import RadarReading
from platoon_sumo.sensors.v2v import V2VInbox, V2VMessage


@dataclass(frozen=True)
class AccParams:
    time_gap_s: float = bounded(1.2, gt=0, le=10)
    """h: time gap kept at speed, bumper to bumper [s]."""
    standstill_gap_m: float = bounded(2.0, ge=0, le=100)
    """r: gap kept at standstill [m]."""
    kp_1ps2: float = bounded(0.2, ge=0, le=10)
    """Gain on the spacing error [1/s²] (Ploeg et al. 2011: 0.2)."""
    kd_1ps: float = bounded(0.7, ge=0, le=10)
    """Gain on the spacing error's rate [1/s] (Ploeg et al. 2011: 0.7)."""
    range_sensor: str = "radar"
    """Name of the sensor giving the gap (`observation.sensors[name]`, a RadarReading)."""
    route: RouteFollowingParams = field(default_factory=RouteFollowingParams)
    """Steering, speed limits, curves and signals (route_following's parameters)."""

    def __post_init__(self) -> None:
        require_positive(self, "time_gap_s")


@dataclass(frozen=True)
class FallbackParams:
    """The V2V channel and the fall-back to ACC when its messages stop (`cacc`,
    `path_cacc`)."""

    channel: str = "v2v"
    """Name of the V2V sensor (`observation.sensors[name]`, a V2VInbox)."""
    message_timeout_s: float = bounded(0.5, gt=0, le=60)
    """A message older than this is stale: fall back to ACC [s]."""
    fallback_time_gap_s: float = bounded(1.2, gt=0, le=10)
    """Time gap of the ACC fall-back [s]."""
    time_gap_rate: float = bounded(0.2, gt=0, le=100)
    """How fast the time gap moves between the cooperative one and the fall-back's
    [s per s]."""


@dataclass(frozen=True)
class CaccParams(FallbackParams, AccParams):
    time_gap_s: float = bounded(0.5, gt=0, le=10)
    """h: time gap kept at speed while the predecessor's messages arrive [s]."""


class GapControl:
    """What the radar laws share: the gap from the range sensor, the own acceleration
    from speeds, route following's cap and steering, the anti-windup and the Command.
    A law (`_law`) returns the desired acceleration and its mode; `_ploeg` is the ACC
    law every fall-back uses."""

    Params: ClassVar[type[Any]]

    def __init__(self, params: Any = None) -> None:
        self.params = params or self.Params()
        self._route = RouteFollowing(self.params.route)
        self.reset()

    def reset(self) -> None:
        self._route.reset()
        self._u_mps2 = 0.0
        self._last_speed_mps: float | None = None
        self._time_gap_s = 0.0

    def _law(self, obs: Observation, reading: RadarReading, accel: float) -> tuple[float, str]:
        """(desired acceleration before the limits, mode) for a radar target ahead."""
        raise NotImplementedError

    def _policy(self) -> GapPolicy:
        raise NotImplementedError

    def _ploeg(
        self, obs: Observation, reading: RadarReading, accel: float, standstill_m: float,
        h: float, kp: float, kd: float, feed_forward: float,
    ) -> float:  # fmt: skip
        """Ploeg et al.'s u after one step of its first-order filter (forward Euler;
        below one step of `h`, as `path_cacc`'s fall-back starts, u follows at once)."""
        ahead_speed = reading.speed_mps if reading.speed_mps is not None else obs.speed_mps
        assert reading.gap_m is not None
        error = reading.gap_m - (standstill_m + h * obs.speed_mps)
        error_rate = ahead_speed - obs.speed_mps - h * accel
        drive = kp * error + kd * error_rate + feed_forward
        return self._u_mps2 + (obs.dt_s / h if h > obs.dt_s else 1.0) * (drive - self._u_mps2)

    def step(self, observation: Observation) -> Command:
        obs, p = observation, self.params
        accel = 0.0
        if self._last_speed_mps is not None:
            accel = (obs.speed_mps - self._last_speed_mps) / obs.dt_s
        self._last_speed_mps = obs.speed_mps
        reading = obs.sensors.get(p.range_sensor)
        if not isinstance(reading, RadarReading) or reading.gap_m is None:
            route = self._route.step(obs)
            self._u_mps2 = (route.speed_mps - obs.speed_mps) / obs.dt_s
            return Command(
                route.speed_mps, route.yaw_rate_radps, route.heading_rad, route.lane_change,
                Telemetry("cruise", None, self._policy(), self._u_mps2),
            )  # fmt: skip
        route = self._route._step(obs, math.inf)
        u, mode = self._law(obs, reading, accel)
        limits = obs.limits
        u = min(max(u, -limits.max_decel_mps2), limits.max_accel_mps2)
        # the route's speed (limits, curves, signals) caps the command; the law's state
        # does not wind up beyond what the vehicle is let to do
        wanted = obs.speed_mps + u * obs.dt_s
        speed = min(max(wanted, 0.0), route.speed_mps)
        self._u_mps2 = (speed - obs.speed_mps) / obs.dt_s if speed < wanted else u
        return Command(
            speed, route.yaw_rate_radps, route.heading_rad, route.lane_change,
            Telemetry(mode, reading.gap_m, self._policy(), self._u_mps2),
        )  # fmt: skip


def fresh_message(
    obs: Observation, params: FallbackParams, index: int, reading: RadarReading | None = None
) -> V2VMessage | None:
    """The newest message of member `index` of the vehicle's platoon, unless it is older
    than `message_timeout_s` or (with `reading`) the radar's target is another vehicle,
    e.g. after a cut-in: not its law to follow."""
    inbox = obs.sensors.get(params.channel)
    if not isinstance(inbox, V2VInbox) or index < 0:
        return None
    message = inbox.from_member(obs.platoon_id, index)
    if message is None or obs.time_s - message.sent_s > params.message_timeout_s:
        return None
    if reading is not None and reading.target_id not in (None, message.sender_id):
        return None
    return message


def ramp(current: float, target: float, rate: float, dt_s: float) -> float:
    """`current` moved towards `target` by at most `rate * dt_s` (the fall-back's time
    gap: a step to a larger gap would brake hard)."""
    step = rate * dt_s
    return current + min(max(target - current, -step), step)


@CONTROLLERS.register("acc")
class Acc(GapControl):
    """Radar-only constant time gap control (the `cacc` law without feed-forward)."""

    Params: ClassVar[type[AccParams]] = AccParams
    reads_link_ahead: ClassVar[bool] = False
    params: AccParams

    def reset(self) -> None:
        super().reset()
        self._time_gap_s = self.params.time_gap_s

    def _feed_forward(self, obs: Observation, reading: RadarReading) -> float | None:
        """The predecessor's desired acceleration, or None (no usable message)."""
        return None

    def _time_gap(self, cooperative: bool, dt_s: float) -> float:
        """h for this step."""
        return self.params.time_gap_s

    def _law(self, obs: Observation, reading: RadarReading, accel: float) -> tuple[float, str]:
        p = self.params
        feed_forward = self._feed_forward(obs, reading)
        h = self._time_gap_s = self._time_gap(feed_forward is not None, obs.dt_s)
        u = self._ploeg(
            obs, reading, accel, p.standstill_gap_m, h, p.kp_1ps2, p.kd_1ps, feed_forward or 0.0
        )
        return u, "cacc" if feed_forward is not None else "acc"

    def _policy(self) -> GapPolicy:
        return GapPolicy(self.params.standstill_gap_m, self._time_gap_s)


@CONTROLLERS.register("cacc")
class Cacc(Acc):
    """Ploeg et al. (2011) CACC: ACC plus the predecessor's broadcast desired
    acceleration, falling back to ACC when its messages stop."""

    Params: ClassVar[type[CaccParams]] = CaccParams
    reads_link_ahead: ClassVar[bool] = False
    params: CaccParams

    def _feed_forward(self, obs: Observation, reading: RadarReading) -> float | None:
        message = fresh_message(obs, self.params, obs.index - 1, reading)
        return None if message is None else message.desired_accel_mps2

    def _time_gap(self, cooperative: bool, dt_s: float) -> float:
        p = self.params
        target = p.time_gap_s if cooperative else p.fallback_time_gap_s
        return ramp(self._time_gap_s, target, p.time_gap_rate, dt_s)
