"""`path_cacc` (Rajamani et al. 2000, as in Plexe) on hand-made observations: the law's
gains and desired acceleration against the closed form, and its fall-back to ACC."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from platoon_sumo.control import CONTROLLERS
from platoon_sumo.control.base import GapPolicy, Observation
from platoon_sumo.control.path_cacc import PathCacc, PathCaccParams
from platoon_sumo.path import RoutePath
from platoon_sumo.sensors.radar import RadarReading
from platoon_sumo.sensors.v2v import V2VInbox, V2VMessage
from platoon_sumo.vehicles import MotionLimits

DT = 0.1
PTS = np.column_stack([np.linspace(0, 2000, 4001), np.zeros(4001)])
PATH = RoutePath.from_pieces([PTS], ["e_0"], [40.0], [3.5], 0.5)


def message(index: int, speed: float, desired: float, sent_s: float, accel: float = 0.0):
    return V2VMessage(f"m{index}", "p", index, sent_s, 0.0, 0.0, speed, accel, desired)


def observation(
    time_s: float, messages: list[V2VMessage], *, index: int = 2, speed: float = 20.0,
    gap: float = 6.0, ahead_speed: float = 21.0, target: str | None = "m1",
) -> Observation:  # fmt: skip
    inbox = V2VInbox(time_s, {m.sender_id: m for m in messages})
    return Observation(
        time_s=time_s, dt_s=DT, vehicle_id=f"m{index}", role="follower", x_m=10.0, y_m=0.0,
        yaw_rad=0.0, speed_mps=speed, front_offset_m=3.6, length_m=4.5, width_m=1.8,
        limits=MotionLimits(40.0, 3.0, 8.0, 1.0), path=PATH,
        sensors={"radar": RadarReading(time_s, gap, ahead_speed, target), "v2v": inbox},
        platoon_id="p", index=index,
    )  # fmt: skip


def both(time_s: float, sent_s: float | None = None) -> list[V2VMessage]:
    """The leader's and the predecessor's beacons (module test values)."""
    sent = time_s if sent_s is None else sent_s
    return [message(0, 22.0, -0.3, sent, accel=0.4), message(1, 21.0, 0.5, sent, accel=-0.2)]


def test_registered() -> None:
    assert CONTROLLERS.get("path_cacc") is PathCacc


def test_gains_from_c1_xi_omega_n() -> None:
    # Rajamani's closed form: at xi = 1 the square root vanishes
    assert PathCaccParams().alphas == pytest.approx((0.5, 0.5, -0.3, -0.1, -0.04))
    root = 2.0 + math.sqrt(3.0)
    p = PathCaccParams(c1=0.3, xi=2.0, omega_n_radps=0.5)
    expected = (0.7, 0.3, -(4.0 - 0.3 * root) * 0.5, -0.3 * root * 0.5, -0.25)
    assert p.alphas == pytest.approx(expected)


def test_desired_acceleration_is_the_closed_form() -> None:
    command = PathCacc().step(observation(3.0, both(3.0)))
    # a1 u_pred + a2 u_lead + a3 (v - v_pred) + a4 (v - v_lead) + a5 (spacing - gap)
    u = 0.5 * 0.5 + 0.5 * -0.3 - 0.3 * (20.0 - 21.0) - 0.1 * (20.0 - 22.0) - 0.04 * (5.0 - 6.0)
    assert u == pytest.approx(0.64)
    assert command.telemetry is not None
    assert command.telemetry.mode == "path_cacc"
    assert command.telemetry.desired_accel_mps2 == pytest.approx(u)
    assert command.telemetry.gap_policy == GapPolicy(5.0, 0.0)
    assert command.speed_mps == pytest.approx(20.0 + u * DT)


def test_achieved_accelerations_on_request() -> None:
    ctrl = PathCacc(PathCaccParams(use_desired_accel=False))
    command = ctrl.step(observation(3.0, both(3.0)))
    u = 0.5 * -0.2 + 0.5 * 0.4 + 0.3 + 0.2 + 0.04
    assert command.telemetry is not None
    assert command.telemetry.desired_accel_mps2 == pytest.approx(u)


def test_the_first_follower_hears_its_predecessor_as_leader() -> None:
    leader = message(0, 22.0, -0.3, 3.0)
    command = PathCacc().step(observation(3.0, [leader], index=1, ahead_speed=22.0, target="m0"))
    u = -0.3 - 0.3 * (20.0 - 22.0) - 0.1 * (20.0 - 22.0) - 0.04 * (5.0 - 6.0)  # a1 + a2 = 1
    assert command.telemetry is not None and command.telemetry.mode == "path_cacc"
    assert command.telemetry.desired_accel_mps2 == pytest.approx(u)


def _fallback_u(h: float, gap: float = 6.0, speed: float = 20.0, ahead: float = 21.0) -> float:
    """Ploeg et al.'s ACC law from u = 0 and zero acceleration, for h below one step
    (u follows its drive at once): kp e + kd e'."""
    return 0.2 * (gap - (5.0 + h * speed)) + 0.7 * (ahead - speed)


@pytest.mark.parametrize("missing", ["leader", "predecessor"])
def test_falls_back_to_acc_when_a_member_is_silent(missing: str) -> None:
    leader, predecessor = both(3.0)
    heard = [predecessor] if missing == "leader" else [leader]
    command = PathCacc().step(observation(3.0, heard))
    assert command.telemetry is not None and command.telemetry.mode == "acc"
    # the time gap starts opening from 0 at 0.2 s per s: 0.02 s after one step
    assert command.telemetry.gap_policy == GapPolicy(5.0, pytest.approx(0.02))
    assert command.telemetry.desired_accel_mps2 == pytest.approx(_fallback_u(0.02))


def test_message_timeout() -> None:
    fresh = PathCacc().step(observation(3.0, both(3.0, sent_s=2.6)))  # 0.4 s old
    stale = PathCacc().step(observation(3.0, both(3.0, sent_s=2.4)))  # 0.6 s old
    assert fresh.telemetry is not None and fresh.telemetry.mode == "path_cacc"
    assert stale.telemetry is not None and stale.telemetry.mode == "acc"


def test_cut_in_falls_back() -> None:
    command = PathCacc().step(observation(3.0, both(3.0), target="car"))
    assert command.telemetry is not None and command.telemetry.mode == "acc"


def test_time_gap_opens_gradually_and_closes_when_messages_return() -> None:
    ctrl = PathCacc()
    gaps, modes = [], []
    for k in range(100):  # 10 s silent, then the beacons again
        t = 3.0 + k * DT
        obs = observation(t, [] if k < 70 else both(t))
        telemetry = ctrl.step(obs).telemetry
        assert telemetry is not None and telemetry.gap_policy is not None
        gaps.append(telemetry.gap_policy.time_gap_s)
        modes.append(telemetry.mode)
    assert modes[:70] == ["acc"] * 70 and modes[70:] == ["path_cacc"] * 30
    assert np.diff(gaps[:60]) == pytest.approx(0.02)  # 0.2 s per s
    assert gaps[59:70] == pytest.approx([1.2] * 11)  # held at fallback_time_gap_s
    assert np.diff(gaps[69:]) == pytest.approx(-0.02)  # and closed at the same rate
    # the PATH law tracks the policy while it closes: spacing + h v
    ctrl2 = PathCacc()
    ctrl2._time_gap_s = 1.0
    telemetry = ctrl2.step(observation(3.0, both(3.0), gap=30.0)).telemetry
    assert telemetry is not None
    u = 0.25 - 0.15 + 0.3 + 0.2 - 0.04 * (5.0 + 0.98 * 20.0 - 30.0)
    assert telemetry.desired_accel_mps2 == pytest.approx(u)


def test_without_radar_target_it_cruises() -> None:
    obs = observation(3.0, both(3.0))
    obs = replace(obs, sensors={**obs.sensors, "radar": RadarReading(3.0, None, None, None)})
    command = PathCacc().step(obs)
    assert command.telemetry is not None and command.telemetry.mode == "cruise"
