"""A leader that drives a prescribed speed profile along its route (disturbance tests).

The standard platooning stability tests excite the platoon from its leader: a sinusoidal
speed, one hard braking, or repeated stop-and-go, after a warm-up at cruise speed. This
controller steers and obeys signals and the vehicle ahead like ``route_following`` (it
uses one inside) and commands ``min(profile(t), route_following speed)``, where ``t`` is
the time since the vehicle's first step. The vehicle model's acceleration limits still
apply, so a profile steeper than the vehicle can drive is followed as fast as it can.

Profiles (``v0`` = ``cruise_speed_mps``, ``t0`` = ``start_s``):

- ``constant``: ``v0``.
- ``sinusoid``: ``v0 + amplitude_mps * sin(2 pi (t - t0) / period_s)`` for ``t0 <= t <
  t0 + cycles * period_s`` (``cycles`` None: until the end), else ``v0``.
- ``brake``: ``v0`` until ``t0``, then down to ``low_speed_mps`` at ``decel_mps2``,
  ``hold_s`` there, back up to ``v0`` at ``accel_mps2``.
- ``stop_and_go``: the ``brake`` cycle repeated every ``period_s`` (from ``t0``),
  ``cycles`` times (None: until the end).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import ClassVar, Literal

from platoon_sumo.config_loader import bounded, require, require_choice, require_positive
from platoon_sumo.control.base import CONTROLLERS, Command, Observation
from platoon_sumo.control.route_following import RouteFollowing, RouteFollowingParams

_PROFILES = ("constant", "sinusoid", "brake", "stop_and_go")


@dataclass(frozen=True)
class SpeedProfileParams:
    """Speed profile of a disturbance leader; times from the vehicle's first step."""

    profile: Literal["constant", "sinusoid", "brake", "stop_and_go"] = "sinusoid"
    """Shape of the profile (see the module docstring)."""
    cruise_speed_mps: float = bounded(15.0, gt=0, le=150)
    """Speed before, between and after the disturbances [m/s]."""
    start_s: float = bounded(30.0, ge=0, le=10_000_000)
    """Warm-up at cruise speed before the first disturbance [s]."""
    amplitude_mps: float = bounded(3.0, ge=0, le=150)
    """Sinusoid amplitude [m/s]."""
    period_s: float = bounded(10.0, gt=0, le=10_000_000)
    """Sinusoid period, or time between stop-and-go cycles [s]."""
    cycles: int | None = bounded(None, ge=1, le=1_000_000)
    """Number of sinusoid periods or stop-and-go cycles; None: until the run ends."""
    low_speed_mps: float = bounded(0.0, ge=0, le=150)
    """Speed the brake and stop-and-go profiles brake down to [m/s]."""
    decel_mps2: float = bounded(6.0, gt=0, le=50)
    """Deceleration of the brake and stop-and-go profiles [m/s²]."""
    accel_mps2: float = bounded(1.5, gt=0, le=50)
    """Acceleration back to cruise speed [m/s²]."""
    hold_s: float = bounded(5.0, ge=0, le=10_000_000)
    """Time spent at `low_speed_mps` [s]."""
    route: RouteFollowingParams = field(default_factory=RouteFollowingParams)
    """Steering, signals and vehicle-ahead behaviour (route_following's parameters)."""

    def __post_init__(self) -> None:
        require_choice(self.profile, _PROFILES, "profile")
        require_positive(self, "cruise_speed_mps", "period_s", "decel_mps2", "accel_mps2")
        require_positive(
            self, "start_s", "amplitude_mps", "low_speed_mps", "hold_s", allow_zero=True
        )
        require(self.low_speed_mps <= self.cruise_speed_mps, "low_speed_mps",
                "must be <= cruise_speed_mps")  # fmt: skip
        require(self.cycles is None or self.cycles >= 1, "cycles", "must be >= 1")


def profile_speed(p: SpeedProfileParams, t_s: float) -> float:
    """The profile's speed [m/s] at `t_s` seconds after the vehicle's first step."""
    v0, tau = p.cruise_speed_mps, t_s - p.start_s
    if p.profile == "constant" or tau < 0.0:
        return v0
    if p.profile == "sinusoid":
        if p.cycles is not None and tau >= p.cycles * p.period_s:
            return v0
        return max(v0 + p.amplitude_mps * math.sin(2.0 * math.pi * tau / p.period_s), 0.0)
    if p.profile == "stop_and_go":
        cycle = int(tau // p.period_s)
        if p.cycles is not None and cycle >= p.cycles:
            return v0
        tau -= cycle * p.period_s
    return _brake_cycle(p, tau)


def _brake_cycle(p: SpeedProfileParams, tau: float) -> float:
    """Brake from cruise to the low speed, hold, accelerate back; `tau` from its start."""
    v0, low = p.cruise_speed_mps, p.low_speed_mps
    t_down = (v0 - low) / p.decel_mps2
    if tau < t_down:
        return v0 - p.decel_mps2 * tau
    tau -= t_down
    if tau < p.hold_s:
        return low
    return min(low + p.accel_mps2 * (tau - p.hold_s), v0)


@CONTROLLERS.register("speed_profile")
class SpeedProfileLeader:
    """Route following with the speed capped by a time profile (see the module docstring)."""

    Params: ClassVar[type[SpeedProfileParams]] = SpeedProfileParams
    reads_link_ahead: ClassVar[bool] = False

    def __init__(self, params: SpeedProfileParams | None = None):
        self.params = params or SpeedProfileParams()
        self._route = RouteFollowing(self.params.route)
        self._t0_s: float | None = None

    def reset(self) -> None:
        self._route.reset()
        self._t0_s = None

    def step(self, observation: Observation) -> Command:
        if self._t0_s is None:
            self._t0_s = observation.time_s
        cmd = self._route.step(observation)
        target = profile_speed(self.params, observation.time_s - self._t0_s)
        # the route's steering and lane requests as they are, the speed capped
        return dataclasses.replace(cmd, speed_mps=min(cmd.speed_mps, target))
