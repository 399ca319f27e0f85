"""Vehicle models against closed-form motion (circles, lines, ramps) and their limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.geometry import wrap_angle
from platoon_sumo.registry import Registry
from platoon_sumo.scenario import VehicleConfig, load_scenario
from platoon_sumo.vehicles import (
    VEHICLE_MODELS,
    Bicycle,
    KinematicState,
    MotionLimits,
    Powertrain,
    Unicycle,
    VehicleModel,
    heading_to_yaw_rate,
    integrate_arc,
    powertrain_speed,
)
from tests.helpers import REPO

ROBOT = MotionLimits(
    max_speed_mps=0.5, max_accel_mps2=0.5, max_decel_mps2=1.0, max_yaw_rate_radps=1.5
)
CAR = MotionLimits(
    max_speed_mps=40.0,
    max_accel_mps2=2.6,
    max_decel_mps2=9.0,
    max_yaw_rate_radps=1.0,
    max_steer_rad=0.5,
    wheelbase_m=2.7,
)
MODELS = [Unicycle(), Bicycle()]


def run(
    model: VehicleModel,
    state: KinematicState,
    speed_cmd: float | np.ndarray,
    yaw_rate_cmd: float | np.ndarray,
    limits: MotionLimits,
    dt_s: float,
    steps: int,
) -> list[KinematicState]:
    n = len(state)
    v_cmd = np.broadcast_to(np.asarray(speed_cmd, dtype=np.float64), (n,))
    w_cmd = np.broadcast_to(np.asarray(yaw_rate_cmd, dtype=np.float64), (n,))
    states = [state]
    for _ in range(steps):
        states.append(model.step(states[-1], v_cmd, w_cmd, limits, dt_s))
    return states


def circle_centre(state: KinematicState, radius_m: float) -> tuple[float, float]:
    """Centre of a left turn (radius > 0) starting from the state's pose."""
    x, y, yaw = state.x_m[0], state.y_m[0], state.yaw_rad[0]
    return x - radius_m * math.sin(yaw), y + radius_m * math.cos(yaw)


# ---------------------------------------------------------------- limits and state


def test_motion_limits_validation_names_the_field() -> None:
    good = {
        "max_speed_mps": 1.0,
        "max_accel_mps2": 1.0,
        "max_decel_mps2": 1.0,
        "max_yaw_rate_radps": 1.0,
    }
    MotionLimits(**good)
    for key in good:
        for bad in (0.0, -1.0, math.nan, math.inf):
            with pytest.raises(ValueError, match=key):
                MotionLimits(**{**good, key: bad})
    for bad_steer in (0.0, math.pi / 2, 2.0):
        with pytest.raises(ValueError, match="max_steer_rad"):
            MotionLimits(**good, max_steer_rad=bad_steer)
    with pytest.raises(ValueError, match="wheelbase_m"):
        MotionLimits(**good, wheelbase_m=0.0)
    with pytest.raises(ValueError, match="max_speed_mps"):
        MotionLimits(**{**good, "max_speed_mps": "fast"})  # type: ignore[arg-type]
    assert CAR.min_turning_radius_m == pytest.approx(2.7 / math.tan(0.5))


def test_kinematic_state_of_len_take() -> None:
    s = KinematicState.of([0.0, 1.0, 2.0], 5.0, 0.0, [1.0, 2.0, 3.0])
    assert len(s) == 3
    assert s.x_m.dtype == np.float64 and s.y_m.shape == (3,)
    np.testing.assert_array_equal(s.y_m, [5.0, 5.0, 5.0])
    sub = s.take([2, 0])
    np.testing.assert_array_equal(sub.x_m, [2.0, 0.0])
    np.testing.assert_array_equal(sub.speed_mps, [3.0, 1.0])
    np.testing.assert_array_equal(s.take(np.array([False, True, False])).x_m, [1.0])
    single = KinematicState.of(1.0, 2.0, 3 * math.pi, 0.0)
    assert len(single) == 1 and single.yaw_rad[0] == pytest.approx(-math.pi)
    with pytest.raises(ValueError, match="speed_mps"):
        KinematicState(np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(3))
    with pytest.raises(ValueError, match="x_m"):
        KinematicState(np.zeros((2, 2)), np.zeros(2), np.zeros(2), np.zeros(2))


def test_of_copies_inputs() -> None:
    x = np.array([1.0, 2.0])
    s = KinematicState.of(x, 0.0, 0.0, 0.0)
    x[0] = 99.0
    assert s.x_m[0] == 1.0


# ---------------------------------------------------------------- exact pose integration


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
@pytest.mark.parametrize("yaw_rate", [0.3, -0.2])
def test_constant_command_traces_exact_circle(model: VehicleModel, yaw_rate: float) -> None:
    v, dt = 8.0, 0.1
    state = KinematicState.of(12.0, -3.0, 0.7, v)
    radius = v / yaw_rate  # signed: negative turns right
    cx, cy = circle_centre(state, radius)
    states = run(model, state, v, yaw_rate, CAR, dt, steps=2_000)  # ~25 laps of the circle
    xs = np.array([s.x_m[0] for s in states])
    ys = np.array([s.y_m[0] for s in states])
    np.testing.assert_allclose(np.hypot(xs - cx, ys - cy), abs(radius), rtol=0, atol=1e-9)
    # Heading advances exactly omega * t.
    expected_yaw = wrap_angle(0.7 + yaw_rate * dt * 2_000)
    assert abs(wrap_angle(states[-1].yaw_rad[0] - expected_yaw)) < 1e-9


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_zero_yaw_rate_is_a_straight_line(model: VehicleModel) -> None:
    yaw, v, dt = -2.0, 3.0, 0.05
    states = run(model, KinematicState.of(1.0, 2.0, yaw, v), v, 0.0, CAR, dt, steps=400)
    t = dt * np.arange(401)
    np.testing.assert_allclose([s.x_m[0] for s in states], 1.0 + v * t * math.cos(yaw), atol=1e-9)
    np.testing.assert_allclose([s.y_m[0] for s in states], 2.0 + v * t * math.sin(yaw), atol=1e-9)
    assert all(s.yaw_rad[0] == yaw for s in states)


@given(
    st.floats(-3.0, 3.0),
    st.floats(0.0, 20.0),
    st.floats(-1.0, 1.0).filter(lambda w: w == 0.0 or abs(w) > 1e-12),
    st.floats(0.01, 1.0),
)
@settings(deadline=None, max_examples=200)
def test_integrate_arc_matches_textbook_formula(yaw: float, v: float, w: float, dt: float) -> None:
    """The sinc form agrees with x += v/w (sin(yaw + w dt) - sin yaw) where that is stable."""
    s = integrate_arc(KinematicState.of(0.0, 0.0, yaw, v), np.array([v]), np.array([w]), dt)
    if abs(w) > 1e-4:  # textbook form; its cancellation error ~ 1e-16 v / w stays < 1e-10
        ex = v / w * (math.sin(yaw + w * dt) - math.sin(yaw))
        ey = v / w * (math.cos(yaw) - math.cos(yaw + w * dt))
    else:  # Taylor series of the arc to third order in w dt (error < 1e-16 here)
        a = w * dt
        ex = v * dt * (math.cos(yaw) - a / 2 * math.sin(yaw) - a * a / 6 * math.cos(yaw))
        ey = v * dt * (math.sin(yaw) + a / 2 * math.cos(yaw) - a * a / 6 * math.sin(yaw))
    assert s.x_m[0] == pytest.approx(ex, abs=1e-9)
    assert s.y_m[0] == pytest.approx(ey, abs=1e-9)


# ---------------------------------------------------------------- speed limits


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_acceleration_limit_ramps_until_command(model: VehicleModel) -> None:
    dt = 0.1
    states = run(model, KinematicState.of(0.0, 0.0, 0.0, 0.0), 0.3, 0.0, ROBOT, dt, steps=15)
    speeds = np.array([s.speed_mps[0] for s in states])
    expected = np.minimum(ROBOT.max_accel_mps2 * dt * np.arange(16), 0.3)
    np.testing.assert_allclose(speeds, expected, atol=1e-12)
    # Position uses the new speed over each step (SUMO's Euler update).
    np.testing.assert_allclose(states[-1].x_m[0], dt * speeds[1:].sum(), atol=1e-12)


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_deceleration_limit_and_no_reverse(model: VehicleModel) -> None:
    dt = 0.5
    states = run(model, KinematicState.of(0.0, 0.0, 0.0, 30.0), -5.0, 0.0, CAR, dt, steps=10)
    speeds = np.array([s.speed_mps[0] for s in states])
    expected = np.maximum(30.0 - CAR.max_decel_mps2 * dt * np.arange(11), 0.0)
    np.testing.assert_allclose(speeds, expected, atol=1e-12)
    assert speeds.min() == 0.0
    xs = np.array([s.x_m[0] for s in states])
    assert np.all(np.diff(xs) >= 0.0)  # never rolls backwards


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_max_speed_clip(model: VehicleModel) -> None:
    states = run(model, KinematicState.of(0.0, 0.0, 0.0, 0.4), 10.0, 0.0, ROBOT, 0.5, steps=5)
    assert [s.speed_mps[0] for s in states[1:]] == [ROBOT.max_speed_mps] * 5


def test_yaw_rate_clip_unicycle_turns_on_the_spot() -> None:
    dt = 0.1
    s = Unicycle().step(
        KinematicState.of(0.0, 0.0, 0.0, 0.0), np.array([0.0]), np.array([10.0]), ROBOT, dt
    )
    assert s.yaw_rad[0] == pytest.approx(ROBOT.max_yaw_rate_radps * dt)
    assert s.x_m[0] == 0.0 and s.y_m[0] == 0.0
    s = Unicycle().step(
        KinematicState.of(0.0, 0.0, 0.0, 0.0), np.array([0.0]), np.array([-10.0]), ROBOT, dt
    )
    assert s.yaw_rad[0] == pytest.approx(-ROBOT.max_yaw_rate_radps * dt)


def test_yaw_rate_clip_bicycle() -> None:
    # At 20 m/s the steering allows 20 tan(0.5) / 2.7 = 4 rad/s, so max_yaw_rate binds.
    s = Bicycle().step(
        KinematicState.of(0.0, 0.0, 0.0, 20.0), np.array([20.0]), np.array([5.0]), CAR, 0.1
    )
    assert s.yaw_rad[0] == pytest.approx(CAR.max_yaw_rate_radps * 0.1)


# ---------------------------------------------------------------- bicycle steering


def test_bicycle_steering_limit_gives_minimum_turning_radius() -> None:
    v, dt = 2.0, 0.05  # slow enough that the steering limit binds, not max_yaw_rate
    radius = CAR.wheelbase_m / math.tan(CAR.max_steer_rad)
    assert v / radius < CAR.max_yaw_rate_radps
    state = KinematicState.of(0.0, 0.0, 0.3, v)
    cx, cy = circle_centre(state, radius)
    states = run(Bicycle(), state, v, CAR.max_yaw_rate_radps, CAR, dt, steps=1_000)
    xs = np.array([s.x_m[0] for s in states])
    ys = np.array([s.y_m[0] for s in states])
    np.testing.assert_allclose(np.hypot(xs - cx, ys - cy), radius, rtol=0, atol=1e-9)
    # The unicycle under the same command turns much tighter.
    uni = run(Unicycle(), state, v, CAR.max_yaw_rate_radps, CAR, dt, steps=10)
    assert uni[-1].yaw_rad[0] - 0.3 > states[10].yaw_rad[0] - 0.3


def test_bicycle_at_standstill_does_not_turn() -> None:
    state = KinematicState.of(1.0, 2.0, 0.5, 0.0)
    s = Bicycle().step(state, np.array([0.0]), np.array([1.0]), CAR, 0.1)
    assert s.yaw_rad[0] == 0.5 and s.x_m[0] == 1.0 and s.y_m[0] == 2.0
    # Pulling away, the turn is bounded by the (small) new speed.
    s = Bicycle().step(state, np.array([5.0]), np.array([1.0]), CAR, 0.1)
    v_new = CAR.max_accel_mps2 * 0.1
    assert s.yaw_rad[0] - 0.5 == pytest.approx(v_new * math.tan(0.5) / 2.7 * 0.1)


# ---------------------------------------------------------------- vectorisation


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_batch_equals_each_vehicle_alone(model: VehicleModel) -> None:
    rng = np.random.default_rng(3)
    n = 50
    state = KinematicState.of(
        rng.uniform(-100, 100, n),
        rng.uniform(-100, 100, n),
        rng.uniform(-math.pi, math.pi, n),
        rng.uniform(0, 30, n),
    )
    v_cmd = rng.uniform(-5, 45, n)
    w_cmd = rng.uniform(-2, 2, n)
    w_cmd[:5] = 0.0
    batch = model.step(state, v_cmd, w_cmd, CAR, 0.1)
    for k in range(n):
        alone = model.step(state.take([k]), v_cmd[k : k + 1], w_cmd[k : k + 1], CAR, 0.1)
        for name in ("x_m", "y_m", "yaw_rad", "speed_mps"):
            assert getattr(alone, name)[0] == getattr(batch, name)[k], (k, name)


def test_step_rejects_bad_inputs() -> None:
    state = KinematicState.of([0.0, 1.0], 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="speed_cmd_mps"):
        Unicycle().step(state, np.zeros(3), np.zeros(2), ROBOT, 0.1)
    with pytest.raises(ValueError, match="yaw_rate_cmd_radps"):
        Unicycle().step(state, np.zeros(2), np.array([0.0, math.nan]), ROBOT, 0.1)
    with pytest.raises(ValueError, match="dt_s"):
        Unicycle().step(state, np.zeros(2), np.zeros(2), ROBOT, 0.0)
    # Scalars broadcast to every vehicle.
    assert len(Unicycle().step(state, 0.1, 0.0, ROBOT, 0.1)) == 2  # type: ignore[arg-type]


def test_empty_state_steps() -> None:
    empty = KinematicState.of(np.empty(0), np.empty(0), np.empty(0), np.empty(0))
    assert len(Bicycle().step(empty, np.empty(0), np.empty(0), CAR, 0.1)) == 0


# ---------------------------------------------------------------- heading helper


def test_heading_to_yaw_rate() -> None:
    dt = 0.1
    # Within the limit: reaches the target in one step.
    np.testing.assert_allclose(heading_to_yaw_rate(0.1, 0.0, dt, 1.5), [1.0])
    # Beyond it: clipped, signed the short way round (across +-pi).
    np.testing.assert_allclose(heading_to_yaw_rate(-3.0, 3.0, dt, 1.5), [1.5])
    np.testing.assert_allclose(heading_to_yaw_rate(3.0, -3.0, dt, 1.5), [-1.5])
    got = heading_to_yaw_rate(np.array([0.0, 1.0]), np.array([0.05, 0.0]), dt, 2.0)
    np.testing.assert_allclose(got, [-0.5, 2.0])
    s = Unicycle().step(
        KinematicState.of(0.0, 0.0, 0.0, 0.0),
        np.zeros(1),
        heading_to_yaw_rate(0.1, 0.0, dt, 1.5),
        ROBOT,
        dt,
    )
    assert s.yaw_rad[0] == pytest.approx(0.1)


# ---------------------------------------------------------------- registry


def test_registry_has_both_models_and_refuses_duplicates() -> None:
    assert VEHICLE_MODELS.names() == ["bicycle", "unicycle"]
    assert VEHICLE_MODELS.get("unicycle") is Unicycle
    assert VEHICLE_MODELS.get("bicycle") is Bicycle
    for name in VEHICLE_MODELS:
        assert VEHICLE_MODELS.get(name)().name == name
    with pytest.raises(ValueError, match="already registered"):
        VEHICLE_MODELS.register("bicycle")(Unicycle)
    with pytest.raises(LookupError, match="did you mean 'bicycle'"):
        VEHICLE_MODELS.get("bicycel")
    assert isinstance(VEHICLE_MODELS, Registry)


def _drive_powertrain(
    powertrain: Powertrain, speed_cmd: float, steps: int, dt: float = 0.1, v0: float = 10.0
) -> np.ndarray:
    """Accelerations achieved step by step under a constant speed command."""
    speed, accel, out = np.array([v0]), np.array([0.0]), []
    for _ in range(steps):
        new = powertrain_speed(speed, accel, np.array([speed_cmd]), powertrain, CAR, dt)
        accel, speed = (new - speed) / dt, new
        out.append(float(accel[0]))
    return np.array(out)


@pytest.mark.parametrize("lag_s", [0.1, 0.5, 1.3])
def test_lag_step_response_matches_first_order_closed_form(lag_s: float) -> None:
    # a command far above the speed asks for max_accel throughout: a(t) = a_max (1 - e^-t/lag)
    dt = 0.1
    achieved = _drive_powertrain(Powertrain(lag_s=lag_s), speed_cmd=1e3, steps=60, dt=dt)
    t = dt * np.arange(1, 61)
    expected = CAR.max_accel_mps2 * (1.0 - np.exp(-t / lag_s))
    np.testing.assert_allclose(achieved, expected, rtol=0, atol=1e-9)


def test_jerk_bound_ramps_the_acceleration() -> None:
    achieved = _drive_powertrain(Powertrain(max_jerk_mps3=2.0), speed_cmd=1e3, steps=30)
    expected = np.minimum(2.0 * 0.1 * np.arange(1, 31), CAR.max_accel_mps2)
    np.testing.assert_allclose(achieved, expected, atol=1e-9)
    braking = _drive_powertrain(Powertrain(max_jerk_mps3=2.0), speed_cmd=0.0, steps=5, v0=30.0)
    np.testing.assert_allclose(braking, -0.2 * np.arange(1, 6), atol=1e-9)


def test_ideal_powertrain_reaches_the_command_within_the_limits() -> None:
    speed = np.array([10.0, 10.0, 10.0, 0.1])
    cmd = np.array([10.1, 30.0, 0.0, 0.0])
    new = powertrain_speed(speed, np.zeros(4), cmd, Powertrain(), CAR, 0.1)
    dv_up, dv_down = CAR.max_accel_mps2 * 0.1, CAR.max_decel_mps2 * 0.1
    np.testing.assert_allclose(new, [10.1, 10.0 + dv_up, 10.0 - dv_down, 0.0])


@settings(max_examples=200, deadline=None)
@given(
    speed=st.floats(0, 40),
    accel=st.floats(-9, 3),
    cmd=st.floats(0, 40),
    lag=st.floats(0, 2),
    jerk=st.one_of(st.none(), st.floats(0.1, 50)),
)
def test_powertrain_stays_within_limits(
    speed: float, accel: float, cmd: float, lag: float, jerk: float | None
) -> None:
    dt = 0.1
    pt = Powertrain(lag, jerk)
    new = float(
        powertrain_speed(np.array([speed]), np.array([accel]), np.array([cmd]), pt, CAR, dt)[0]
    )
    assert new >= 0.0
    achieved = (new - speed) / dt
    assert achieved <= CAR.max_accel_mps2 + 1e-9
    assert achieved >= -CAR.max_decel_mps2 - 1e-9 or new == 0.0
    within_limits = -CAR.max_decel_mps2 <= accel <= CAR.max_accel_mps2
    if jerk is not None and new > 0.0 and within_limits:
        assert abs(achieved - accel) <= jerk * dt + 1e-9


def test_the_vehicle_model_gives_the_default_lag_and_a_scenario_value_wins() -> None:
    for name in VEHICLE_MODELS:
        model = VEHICLE_MODELS.get(name)
        assert model.default_actuator_lag_s >= 0.0
        assert VehicleConfig(model=name).powertrain() == Powertrain(model.default_actuator_lag_s)
        assert VehicleConfig(model=name, actuator_lag_s=0.3).powertrain() == Powertrain(0.3)
        assert VehicleConfig(model=name, actuator_lag_s=0.0).powertrain().is_ideal
    assert Unicycle.default_actuator_lag_s == 0.0  # the paper's robots: no lag


@pytest.mark.parametrize(
    ("scenario", "lag_s"), [("paper_world.yaml", 0.0), ("protocols/sinusoid.yaml", 0.1)]
)
def test_shipped_scenarios_powertrains(scenario: str, lag_s: float) -> None:
    (platoon, *_) = load_scenario(REPO / "scenarios" / scenario).scenario.platoons
    assert platoon.vehicle.powertrain() == Powertrain(lag_s)
