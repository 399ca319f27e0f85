"""The speed-profile leader: profile shapes with known values, and the command cap."""

from __future__ import annotations

import numpy as np
import pytest

from platoon_sumo.config_loader import FieldError
from platoon_sumo.control import CONTROLLERS
from platoon_sumo.control.base import Controller, Observation
from platoon_sumo.control.route_following import RouteFollowing, RouteFollowingParams
from platoon_sumo.control.speed_profile import SpeedProfileParams, profile_speed
from platoon_sumo.path import RoutePath
from platoon_sumo.vehicles import MotionLimits


def test_sinusoid_after_the_warm_up_for_the_given_cycles():
    p = SpeedProfileParams(profile="sinusoid", cruise_speed_mps=15.0, start_s=30.0,
                           amplitude_mps=3.0, period_s=10.0, cycles=2)  # fmt: skip
    assert profile_speed(p, 10.0) == 15.0
    assert profile_speed(p, 32.5) == pytest.approx(18.0)  # quarter period: +amplitude
    assert profile_speed(p, 37.5) == pytest.approx(12.0)
    assert profile_speed(p, 52.5) == 15.0  # after two cycles


def test_brake_profile_ramps_down_holds_and_recovers():
    p = SpeedProfileParams(profile="brake", cruise_speed_mps=20.0, start_s=10.0,
                           low_speed_mps=5.0, decel_mps2=5.0, accel_mps2=1.0,
                           hold_s=4.0)  # fmt: skip
    assert profile_speed(p, 9.0) == 20.0
    assert profile_speed(p, 11.0) == pytest.approx(15.0)  # 1 s at 5 m/s²
    assert profile_speed(p, 14.0) == pytest.approx(5.0)  # down after 3 s, holding
    assert profile_speed(p, 18.0) == pytest.approx(6.0)  # 1 s after the 4 s hold (13-17 s)
    assert profile_speed(p, 100.0) == 20.0


def test_stop_and_go_repeats_the_brake_cycle():
    p = SpeedProfileParams(profile="stop_and_go", cruise_speed_mps=10.0, start_s=0.0,
                           period_s=30.0, decel_mps2=5.0, accel_mps2=2.0, hold_s=3.0,
                           cycles=2)  # fmt: skip
    assert profile_speed(p, 4.0) == 0.0
    assert profile_speed(p, 34.0) == 0.0  # second cycle
    assert profile_speed(p, 64.0) == 10.0  # no third cycle


def test_bad_params_name_the_key():
    with pytest.raises(FieldError) as err:
        SpeedProfileParams(low_speed_mps=30.0, cruise_speed_mps=10.0)
    assert err.value.key == "low_speed_mps"


def constant_leader_on_a_straight(lane_offset_m: float = 0.0) -> tuple[Controller, Observation]:
    """A 5 m/s constant-profile leader at 4 m/s on a straight 500 m road, `lane_offset_m`
    left of its route (the lane SUMO keeps it in, under lane actuation)."""
    ctrl = CONTROLLERS.get("speed_profile")(
        SpeedProfileParams(profile="constant", cruise_speed_mps=5.0)
    )
    ctrl.reset()
    pts = np.column_stack([np.linspace(0, 500, 1001), np.zeros(1001)])
    path = RoutePath.from_pieces([pts], ["e_0"], [27.0], [3.5], 0.5)
    obs = Observation(time_s=0.0, dt_s=0.1, vehicle_id="v", role="leader", x_m=0.0,
                      y_m=lane_offset_m, yaw_rad=0.0, speed_mps=4.0, front_offset_m=3.6,
                      length_m=4.5, width_m=1.8, limits=MotionLimits(30.0, 3.0, 8.0, 1.0),
                      path=path, lane_offset_m=lane_offset_m)  # fmt: skip
    return ctrl, obs


def test_command_is_capped_by_the_profile():
    ctrl, obs = constant_leader_on_a_straight()
    assert ctrl.step(obs).speed_mps == pytest.approx(5.0)


def test_the_routes_lane_requests_pass_through_the_profile():
    """Under lane actuation a disturbance leader one lane left of its route asks to move
    right like route following does; only the speed is the profile's."""
    ctrl, obs = constant_leader_on_a_straight(lane_offset_m=3.5)
    route = RouteFollowing(RouteFollowingParams()).step(obs)
    assert route.lane_change == -1
    cmd = ctrl.step(obs)
    assert cmd.lane_change == route.lane_change
    assert cmd.yaw_rate_radps == route.yaw_rate_radps
    assert cmd.speed_mps == pytest.approx(5.0)
