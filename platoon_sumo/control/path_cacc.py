"""`path_cacc`: the PATH constant-spacing CACC (Rajamani et al. 2000), as Plexe runs it.

Rajamani, Tan, Law and Zhang, "Demonstration of integrated longitudinal and lateral
control for the operation of automated vehicles in platoons", IEEE Transactions on
Control Systems Technology 8(4), 2000; the law and its parameters as in Rajamani,
"Vehicle Dynamics and Control" (Springer), ch. 7, the form Plexe implements as its CACC:

    eps  = (spacing + h v) - gap                 spacing error (h = 0 while cooperating)
    eps' = v - v_pred
    u    = a1 a_pred + a2 a_lead + a3 eps' + a4 (v - v_lead) + a5 eps

    a1 = 1 - C1     a2 = C1     a3 = -(2 xi - C1 (xi + sqrt(xi² - 1))) omega_n
    a4 = -C1 (xi + sqrt(xi² - 1)) omega_n        a5 = -omega_n²

A constant spacing (5 m) at any speed is string stable only because every follower also
hears the platoon leader (member 0): `C1` weighs the leader's acceleration against the
predecessor's, `xi` and `omega_n` set the spacing error's damping and bandwidth. The gap
comes from the range sensor (the `radar` by default) as for `acc` and `cacc`; the
predecessor's and the leader's speeds and accelerations from their V2V beacons, as in
Plexe (its default `useControllerAcceleration`: the desired accelerations `u` they
broadcast). Defaults are Plexe's: spacing 5 m, C1 0.5, xi 1, omega_n 0.2 rad/s.

Fall-back: without a fresh beacon from the predecessor or from the leader (older than
`message_timeout_s`), or when the radar's target is not the predecessor (a cut-in), the
follower drives `acc` (Ploeg et al.'s law without feed-forward, `kp_1ps2` / `kd_1ps`) on
the policy `spacing_m + h v`, whose time gap `h` opens from 0 to `fallback_time_gap_s`
at `time_gap_rate` (the spacing policy is continuous at the switch, and a step to a
1.2 s gap at 100 km/h would brake hard). When both beacons return the PATH law resumes
on the same policy while `h` closes back to 0 at the same rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

from platoon_sumo.config_loader import bounded
from platoon_sumo.control.base import CONTROLLERS, GapPolicy, Observation
from platoon_sumo.control.cacc import FallbackParams, GapControl, fresh_message, ramp
from platoon_sumo.control.route_following import RouteFollowingParams
from platoon_sumo.sensors.radar import RadarReading
from platoon_sumo.sensors.v2v import V2VMessage


@dataclass(frozen=True)
class PathCaccParams(FallbackParams):
    spacing_m: float = bounded(5.0, ge=0, le=100)
    """Constant gap kept at every speed, bumper to bumper [m] (Plexe: 5)."""
    c1: float = bounded(0.5, ge=0, le=1)
    """C1: weight of the leader's acceleration against the predecessor's (Plexe: 0.5); 0
    ignores the leader, which a constant spacing cannot afford."""
    xi: float = bounded(1.0, ge=1, le=10)
    """Damping ratio of the spacing error (Plexe: 1; at least 1, the law's gains need
    `sqrt(xi² - 1)`)."""
    omega_n_radps: float = bounded(0.2, gt=0, le=10)
    """Bandwidth of the spacing error's response [rad/s] (Plexe: 0.2)."""
    use_desired_accel: bool = True
    """Feed the desired accelerations `u` the predecessor and leader broadcast (Plexe's
    default); false: the accelerations they achieved, as Rajamani's measured ones."""
    kp_1ps2: float = bounded(0.2, ge=0, le=10)
    """The ACC fall-back's gain on the spacing error [1/s²] (Ploeg et al. 2011: 0.2)."""
    kd_1ps: float = bounded(0.7, ge=0, le=10)
    """The ACC fall-back's gain on the spacing error's rate [1/s] (Ploeg et al.: 0.7)."""
    range_sensor: str = "radar"
    """Name of the sensor giving the gap (`observation.sensors[name]`, a RadarReading)."""
    route: RouteFollowingParams = field(default_factory=RouteFollowingParams)
    """Steering, speed limits, curves and signals (route_following's parameters)."""

    @property
    def alphas(self) -> tuple[float, float, float, float, float]:
        """(a1, ..., a5) of the law from C1, xi and omega_n."""
        root = self.xi + math.sqrt(self.xi**2 - 1.0)
        c1, wn = self.c1, self.omega_n_radps
        return (1.0 - c1, c1, -(2.0 * self.xi - c1 * root) * wn, -c1 * root * wn, -(wn**2))


def path_accel(
    p: PathCaccParams, gap_m: float, desired_gap_m: float, speed_mps: float,
    predecessor: V2VMessage, leader: V2VMessage,
) -> float:  # fmt: skip
    """The PATH law's desired acceleration (module docstring) from the measured gap and
    the predecessor's and leader's beacons."""
    a1, a2, a3, a4, a5 = p.alphas
    if p.use_desired_accel:
        a_pred, a_lead = predecessor.desired_accel_mps2, leader.desired_accel_mps2
    else:
        a_pred, a_lead = predecessor.accel_mps2, leader.accel_mps2
    eps = desired_gap_m - gap_m
    eps_rate = speed_mps - predecessor.speed_mps
    return (
        a1 * a_pred + a2 * a_lead + a3 * eps_rate
        + a4 * (speed_mps - leader.speed_mps) + a5 * eps
    )  # fmt: skip


@CONTROLLERS.register("path_cacc")
class PathCacc(GapControl):
    """PATH constant-spacing CACC (Rajamani et al. 2000, as in Plexe): the predecessor's
    and the leader's beacons, falling back to ACC with an opening time gap when either
    stops."""

    Params: ClassVar[type[PathCaccParams]] = PathCaccParams
    reads_link_ahead: ClassVar[bool] = False
    params: PathCaccParams

    def _law(self, obs: Observation, reading: RadarReading, accel: float) -> tuple[float, str]:
        p = self.params
        assert reading.gap_m is not None
        predecessor = fresh_message(obs, p, obs.index - 1, reading)
        leader = fresh_message(obs, p, 0) if obs.index >= 1 else None
        cooperative = predecessor is not None and leader is not None
        target = 0.0 if cooperative else p.fallback_time_gap_s
        h = self._time_gap_s = ramp(self._time_gap_s, target, p.time_gap_rate, obs.dt_s)
        if predecessor is None or leader is None:
            u = self._ploeg(obs, reading, accel, p.spacing_m, h, p.kp_1ps2, p.kd_1ps, 0.0)
            return u, "acc"
        desired_gap = p.spacing_m + h * obs.speed_mps
        u = path_accel(p, reading.gap_m, desired_gap, obs.speed_mps, predecessor, leader)
        return u, "path_cacc"

    def _policy(self) -> GapPolicy:
        return GapPolicy(self.params.spacing_m, self._time_gap_s)
