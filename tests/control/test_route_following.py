"""Route following in closed loop with the bicycle model, on synthetic paths (no SUMO)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from platoon_sumo.control.base import Observation
from platoon_sumo.control.route_following import RouteFollowing, RouteFollowingParams
from platoon_sumo.kernels.path import profile_speed_kernel
from platoon_sumo.path import RoutePath
from platoon_sumo.vehicles import Bicycle, KinematicState, MotionLimits
from platoon_sumo.world import SignalAhead, VehicleAhead

LIMITS = MotionLimits(
    max_speed_mps=15.0,
    max_accel_mps2=2.5,
    max_decel_mps2=7.5,
    max_yaw_rate_radps=1.0,
    max_steer_rad=0.6,
    wheelbase_m=2.7,
)
FRONT_OFFSET_M = 3.6  # rear axle to front bumper of a 4.5 m car
DT = 0.1


def l_shaped_path(turn_radius_m: float = 12.0) -> RoutePath:
    """100 m east, a quarter circle to the left, 100 m north; speed limit 13.89 m/s."""
    east = np.column_stack([np.linspace(0, 100, 201), np.zeros(201)])
    t = np.linspace(-math.pi / 2, 0.0, 200)
    arc = np.column_stack([100 + turn_radius_m * np.cos(t), turn_radius_m * (1 + np.sin(t))])
    north = np.column_stack(
        [np.full(201, 100 + turn_radius_m), np.linspace(turn_radius_m, 112, 201)]
    )
    return RoutePath.from_pieces([east, arc, north], ["e", "j", "n"], [13.89] * 3, [3.2] * 3, 0.25)


def drive(
    path, steps, signal_at_s=None, signal_state="r", ahead=None, params=None, signal_seen_m=1e9
):
    """Closed loop: controller -> bicycle model; returns per-step (s_front, offset, v).

    The signal at `signal_at_s` shows `signal_state` once it is within `signal_seen_m`
    (before that it is green: a light that changes late)."""
    ctrl = RouteFollowing(params or RouteFollowingParams())
    ctrl.reset()
    state = KinematicState.of(-FRONT_OFFSET_M, 0.0, 0.0, 0.0)
    model = Bicycle()
    log = []
    for k in range(steps):
        x, y, yaw, v = (float(a[0]) for a in (state.x_m, state.y_m, state.yaw_rad, state.speed_mps))
        fx, fy = x + FRONT_OFFSET_M * math.cos(yaw), y + FRONT_OFFSET_M * math.sin(yaw)
        front = path.project(fx, fy)
        signal = None
        if signal_at_s is not None and front.s_m < signal_at_s:
            to_line = signal_at_s - front.s_m
            shown = signal_state if to_line <= signal_seen_m else "G"
            signal = SignalAhead("tls", 0, shown, to_line)
        obs = Observation(
            time_s=k * DT,
            dt_s=DT,
            vehicle_id="car",
            role="leader",
            x_m=x,
            y_m=y,
            yaw_rad=yaw,
            speed_mps=v,
            front_offset_m=FRONT_OFFSET_M,
            length_m=4.5,
            width_m=1.8,
            limits=LIMITS,
            path=path,
            signal=signal,
            vehicle_ahead=ahead(front.s_m, k * DT) if ahead else None,
        )
        cmd = ctrl.step(obs)
        state = model.step(
            state, np.array([cmd.speed_mps]), np.array([cmd.yaw_rate_radps]), LIMITS, DT
        )
        log.append((front.s_m, front.lateral_offset_m, float(state.speed_mps[0])))
    return np.array(log)


def test_follows_a_turn_within_the_lane_and_slows_for_it():
    path = l_shaped_path()
    log = drive(path, steps=400)
    log = log[log[:, 0] < path.length_m - 1.0]  # the loop removes vehicles at the route's end
    s, offset, v = log.T
    assert s[-1] > 200, "drove through the turn"
    assert np.abs(offset).max() < 0.8  # half a 3.2 m lane is 1.6 m
    in_turn = (s > 105) & (s < 115)
    # Speed in the turn respects the lateral acceleration bound a = v^2 / R (R = 12 m, 2 m/s^2).
    assert v[in_turn].max() <= math.sqrt(2.0 * 12.0) + 0.3
    assert v.max() == pytest.approx(13.89, abs=1e-6)  # and reaches the speed limit elsewhere


def test_stops_before_a_red_stop_line_and_drives_on_green():
    path = l_shaped_path()
    red = drive(path, steps=600, signal_at_s=80.0, signal_state="r")
    s, _, v = red.T
    assert v[-1] == 0.0
    assert 80.0 - 1.0 - 0.5 <= s[-1] <= 80.0  # stop_margin_m = 1 before the line
    green = drive(path, steps=300, signal_at_s=80.0, signal_state="G")
    assert green[-1, 0] > 100


def test_brakes_behind_a_stopped_vehicle():
    path = l_shaped_path()
    obstacle_s = 60.0  # rear bumper of a stopped car on the route

    def ahead(s_front, t):
        return VehicleAhead("other", obstacle_s - s_front, 0.0)

    s, _, v = drive(path, steps=500, ahead=ahead).T
    assert v[-1] < 1e-6
    gap = obstacle_s - s[-1]
    assert 2.5 - 0.5 <= gap <= 2.5 + 1.0  # standstill_gap_m = 2.5
    assert (obstacle_s - s > 0).all()


def test_drives_through_yellow_when_too_close_to_stop_comfortably():
    path = l_shaped_path()
    # At 13.9 m/s the light turns yellow 8 m ahead: stopping would need about 12 m/s^2.
    through = drive(path, steps=200, signal_at_s=70.0, signal_state="y", signal_seen_m=8.0)
    near_light = (through[:, 0] > 60.0) & (through[:, 0] < 72.0)
    assert through[-1, 0] > 70.0 and through[near_light, 2].min() > 13.0
    # Turning yellow 60 m ahead it stops comfortably instead.
    stops = drive(path, steps=300, signal_at_s=70.0, signal_state="y", signal_seen_m=60.0)
    assert stops[-1, 0] < 70.0 and stops[-1, 2] == 0.0


def test_a_car_that_braked_for_yellow_does_not_creep_over_the_line():
    from platoon_sumo.control.rules import signal_speed_limit

    # Slow and 0.4 m before the line (inside the 0.5 m stop margin): hold, on yellow too.
    for state in ("y", "r"):
        limit = signal_speed_limit(SignalAhead("t", 0, state, 0.4), 0.9, 0.1, 2.5, 4.0, 0.5)
        assert limit == 0.0
    # Fast and 0.4 m before the line on yellow: too late to stop, clear the junction.
    assert signal_speed_limit(SignalAhead("t", 0, "y", 0.4), 8.0, 0.1, 2.5, 4.0, 0.5) == math.inf


@pytest.mark.parametrize(("lane_offset_m", "expected"), [(3.2, -1), (-3.2, 1), (0.0, 0)])
def test_lane_actuated_car_asks_for_the_lane_its_route_plans(lane_offset_m, expected):
    """Where SUMO steers, a car a lane beside its route's planned lane asks to move back
    to it (SUMO would change only once it must, maybe too late at a queue)."""
    east = np.column_stack([np.linspace(0, 200, 401), np.zeros(401)])
    path = RoutePath.from_pieces([east], ["e_1"], [13.89], [3.2], 0.5)
    obs = Observation(
        time_s=0.0, dt_s=DT, vehicle_id="car", role="leader", x_m=50.0, y_m=lane_offset_m,
        yaw_rad=0.0, speed_mps=10.0, front_offset_m=FRONT_OFFSET_M, length_m=4.5,
        width_m=1.8, limits=LIMITS, path=path, lane_offset_m=lane_offset_m,
    )  # fmt: skip
    assert RouteFollowing().step(obs).lane_change == expected


@given(
    curve=st.lists(st.floats(0.0, 40.0), min_size=1, max_size=300),
    i0=st.integers(0, 320),
    span=st.integers(0, 320),
    spacing=st.floats(0.02, 2.0),
    front_offset=st.floats(0.0, 5.0),
    decel=st.floats(0.1, 9.0),
    v_max=st.floats(0.0, 60.0),
)
def test_profile_speed_kernel_matches_numpy(curve, i0, span, spacing, front_offset, decel, v_max):
    """The compiled speed-profile look-ahead equals the numpy formula bit for bit."""
    speeds = np.asarray(curve, dtype=np.float64)
    i1 = min(len(speeds), i0 + span)
    ahead = speeds[i0:i1]
    dist = np.maximum(np.arange(len(ahead)) * spacing - front_offset, 0.0)
    want = float(np.sqrt(ahead**2 + 2 * decel * dist).min(initial=v_max))
    got = profile_speed_kernel(speeds, min(i0, i1), i1, spacing, front_offset, decel, v_max)
    assert got == want
