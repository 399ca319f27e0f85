"""The compiled ``RouteFollowing`` (one ``route_step_kernel`` call a step) against the
Python implementation it replaced (``reference_route_following.py``, the test oracle):
the same commands and arc lengths to 1e-9, step by step.

1. Observations recorded from real closed-loop runs (``observation_log.py``; the
   followers' observations serve as a leader's: recorded signals, routes, poses) with
   each log's route-following parameters, and variants: lanes beside the path (lane
   requests), a vehicle ahead, a long speed preview (a fast car), a cruise cap.
2. The scripted closed loops of ``test_route_following.py`` with a twin that steps the
   reference beside the fast one.
3. The pruned kernels against the kernels they shortcut (projection, speed profile),
   bit for bit; NaN and infinite states, and lane ids the kernel cannot read.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tests.control.test_route_following as scripted
from platoon_sumo.control.base import Command, Observation, step_batch
from platoon_sumo.control.route_following import RouteFollowing, RouteFollowingParams
from platoon_sumo.errors import PluginError
from platoon_sumo.kernels.path import profile_speed_kernel, project_kernel
from platoon_sumo.kernels.route import BLOCK, path_blocks, profile_speed_pruned, project_pruned
from platoon_sumo.path import LaneChange, RoutePath
from platoon_sumo.world import VehicleAhead
from tests.control.observation_log import FollowerLog, load, logs
from tests.control.reference_route_following import ReferenceRouteFollowing

TOL = 1e-9

ALL_LOGS = [log for path in logs() for log in load(path)]


def assert_same(
    fast: RouteFollowing, ref: ReferenceRouteFollowing, got: Command, want: Command, where: str
) -> None:
    assert abs(got.speed_mps - want.speed_mps) < TOL, where
    assert abs(got.yaw_rate_radps - want.yaw_rate_radps) < TOL, where
    assert got.lane_change == want.lane_change, where
    assert got.heading_rad is None and want.heading_rad is None, where
    assert got.telemetry is None and want.telemetry is None, where
    assert abs(fast._s_m - ref._s_m) < TOL, where


def replay(
    log: FollowerLog,
    params: RouteFollowingParams,
    change: Callable[[int, Observation], Observation] | None = None,
) -> dict[str, int]:
    fast, ref = RouteFollowing(params), ReferenceRouteFollowing(params)
    seen = {"steps": 0, "lane_requests": 0, "capped": 0}
    for k, obs in enumerate(log.observations):
        if change is not None:
            obs = change(k, obs)
        got, want = fast.step(obs), ref.step(obs)
        assert_same(fast, ref, got, want, f"{log.vehicle_id} step {k} t={obs.time_s:.2f}")
        seen["steps"] += 1
        seen["lane_requests"] += got.lane_change != 0
        seen["capped"] += got.speed_mps < obs.limits.max_speed_mps - 1e-6
    return seen


@pytest.mark.parametrize("k", range(len(ALL_LOGS)), ids=[log.vehicle_id for log in ALL_LOGS])
def test_recorded_observations_replay_identically(k):
    log = ALL_LOGS[k]
    seen = replay(log, log.params.fallback)
    assert seen["steps"] > 300


def _lane_beside(k: int, obs: Observation) -> Observation:
    """A lane to the left or right of the path every other stretch of 100 steps."""
    width = obs.path.lane_width_near(0.0)
    offset = (0.0, width, 0.0, -width)[(k // 100) % 4]
    return dataclasses.replace(obs, lane_offset_m=offset, y_m=obs.y_m + 0.3 * offset)


def _vehicle_ahead(k: int, obs: Observation) -> Observation:
    """A vehicle ahead closing in and opening up again (gaps 0.5 .. 30 m)."""
    gap = 15.25 + 14.75 * math.cos(0.05 * k)
    return dataclasses.replace(obs, vehicle_ahead=VehicleAhead("ahead", gap, 0.2 * (k % 50)))


VARIANTS: dict[str, tuple[dict[str, object], Callable[[int, Observation], Observation] | None]] = {
    "lanes_beside": ({}, _lane_beside),
    "vehicle_ahead": ({}, _vehicle_ahead),
    "cruise_and_smoothing": ({"cruise_speed_mps": 6.0, "curvature_smoothing_m": 9.0}, None),
    "long_lookahead": ({"lookahead_min_m": 9.0, "lookahead_time_s": 2.0}, None),
    "soft_braking": ({"comfort_decel_mps2": 0.4, "speed_limit_factor": 1.5}, None),
}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
@pytest.mark.parametrize("name", ["city_platoons", "urban_platoon", "robot_world"])
def test_recorded_observations_replay_identically_with_variants(name, variant):
    log = next(lg for p in logs() if p.name.startswith(name) for lg in load(p))
    changes, change = VARIANTS[variant]
    seen = replay(log, dataclasses.replace(log.params.fallback, **changes), change)  # type: ignore[arg-type]
    if variant == "lanes_beside" and name != "robot_world":
        assert seen["lane_requests"] > 50


def test_a_fast_car_previews_far_and_stops_early():
    """Limits of 55 m/s: a preview of hundreds of metres (the pruned look-ahead stops
    long before its end)."""
    log = next(lg for p in logs() if p.name.startswith("city") for lg in load(p))

    def fast_car(k: int, obs: Observation) -> Observation:
        limits = dataclasses.replace(obs.limits, max_speed_mps=55.0)
        return dataclasses.replace(obs, limits=limits, speed_mps=obs.speed_mps * 2.0)

    replay(log, log.params.fallback, fast_car)


# ----------------------------------------------------------------------------- batched


class _OwnStep(RouteFollowing):
    """A subclass with its own ``step``: ``step_many`` must step it with that."""

    def step(self, observation: Observation) -> Command:
        return dataclasses.replace(super().step(observation), speed_mps=0.25)


def test_many_vehicles_stepped_together_get_the_commands_of_their_own_steps():
    """``RouteFollowing.step_many`` (one ``route_batch_kernel`` call for the group, on
    the paths' stacked tables) against each controller's own ``step``, bit for bit:
    recorded logs of several networks with every variant (lanes beside, a vehicle
    ahead, other parameters), and a subclass with its own ``step`` in the group."""
    cases = []
    for k, log in enumerate(ALL_LOGS[:6]):
        for variant in sorted(VARIANTS):
            changes, change = VARIANTS[variant]
            params = dataclasses.replace(log.params.fallback, **changes)  # type: ignore[arg-type]
            cls = _OwnStep if (k, variant) == (1, "vehicle_ahead") else RouteFollowing
            cases.append((log, change, cls(params), cls(params)))
    steps = min(len(log.observations) for log, *_ in cases)
    assert steps > 300 and len({id(log.observations[0].path) for log, *_ in cases}) > 2
    requests = 0
    for k in range(steps):
        observations = []
        for log, change, _, _ in cases:
            obs = log.observations[k]
            observations.append(change(k, obs) if change is not None else obs)
        together = RouteFollowing.step_many([c for *_, c in cases], observations)
        for (_, _, alone, batched), obs, got in zip(cases, observations, together, strict=True):
            want = alone.step(obs)
            assert got == want, f"{obs.vehicle_id} step {k}"
            assert batched._s_m == alone._s_m
            requests += got.lane_change != 0
    assert requests > 100


def test_a_vehicle_whose_batched_step_fails_is_the_one_named():
    """A non-finite pose in the middle of a group: the run's error names that vehicle."""
    log = ALL_LOGS[0]
    observations = [
        dataclasses.replace(log.observations[10], vehicle_id=f"car{k}", x_m=x)
        for k, x in enumerate([log.observations[10].x_m, math.nan, log.observations[10].x_m])
    ]
    controllers = [RouteFollowing(log.params.fallback) for _ in observations]
    with pytest.raises(PluginError, match=r"vehicle 'car1' failed .*non-finite"):
        step_batch(controllers, observations)


# ----------------------------------------------------------------------------- scripted


class TwinRouteFollowing(RouteFollowing):
    """A ``RouteFollowing`` that steps the reference beside itself and compares."""

    steps = 0

    def __init__(self, params: RouteFollowingParams | None = None):
        super().__init__(params)
        self.reference = ReferenceRouteFollowing(self.params)

    def reset(self) -> None:
        super().reset()
        self.reference.reset()

    def step(self, observation: Observation) -> Command:
        got = super().step(observation)
        want = self.reference.step(observation)
        assert_same(self, self.reference, got, want, f"t={observation.time_s:.2f}")
        TwinRouteFollowing.steps += 1
        return got


SCRIPTED: list[tuple[str, dict[str, object]]] = [
    ("test_follows_a_turn_within_the_lane_and_slows_for_it", {}),
    ("test_stops_before_a_red_stop_line_and_drives_on_green", {}),
    ("test_brakes_behind_a_stopped_vehicle", {}),
    ("test_drives_through_yellow_when_too_close_to_stop_comfortably", {}),
    (
        "test_lane_actuated_car_asks_for_the_lane_its_route_plans",
        {"lane_offset_m": 3.2, "expected": -1},
    ),
    (
        "test_lane_actuated_car_asks_for_the_lane_its_route_plans",
        {"lane_offset_m": -3.2, "expected": 1},
    ),
]


@pytest.mark.parametrize(
    ("name", "kwargs"), SCRIPTED, ids=[f"{n[5:]}-{i}" for i, (n, _) in enumerate(SCRIPTED)]
)
def test_scripted_closed_loops_match_the_reference(monkeypatch, name, kwargs):
    monkeypatch.setattr(scripted, "RouteFollowing", TwinRouteFollowing)
    before = TwinRouteFollowing.steps
    getattr(scripted, name)(**kwargs)
    assert TwinRouteFollowing.steps > before


# ----------------------------------------------------------------------------- kernels


def _polyline(draw_angles: list[float], spacing: float) -> RoutePath:
    """A path from a turtle walk (loops and passes over itself included)."""
    pts = [(0.0, 0.0)]
    heading = 0.0
    for turn in draw_angles:
        heading += turn
        x, y = pts[-1]
        pts.append((x + 3.0 * math.cos(heading), y + 3.0 * math.sin(heading)))
    return RoutePath.from_pieces([np.array(pts)], ["e_0"], [10.0], [3.2], spacing)


@settings(max_examples=300, deadline=None)
@given(
    turns=st.lists(st.floats(-2.0, 2.0), min_size=2, max_size=60),
    spacing=st.sampled_from([0.0375, 0.25, 0.5, 1.3]),
    x=st.floats(-60.0, 120.0),
    y=st.floats(-90.0, 90.0),
    hint=st.one_of(st.none(), st.floats(-20.0, 250.0)),
    window=st.floats(0.0, 80.0),
)
def test_pruned_projection_equals_the_full_window_search(turns, spacing, x, y, hint, window):
    """Bit for bit, on paths that loop and pass over themselves (ties: the first wins)."""
    path = _polyline(turns, spacing)
    xy = np.ascontiguousarray(path.xy_m)
    widths = np.ascontiguousarray(path.lane_width_m)
    blocks = path_blocks(xy)
    assert len(blocks) * BLOCK >= len(xy) - 1
    use_hint = hint is not None
    args = (path.spacing_m, path.length_m, use_hint, hint or 0.0, window, x, y)
    assert project_pruned(xy, blocks, widths, *args) == project_kernel(xy, widths, *args)


def test_pruned_projection_ties_and_odd_values():
    """Equally near segments (the centre of a circle, a path back over itself) and NaN or
    infinite points give what the full search gives."""
    t = np.linspace(0.0, 2.0 * math.pi, 400)
    circle = np.column_stack([10.0 * np.cos(t), 10.0 * np.sin(t)])
    back = np.array([[0.0, 0.0], [50.0, 0.0], [0.0, 0.0], [50.0, 0.0]])
    for pts in (circle, back):
        path = RoutePath.from_pieces([pts], ["e_0"], [10.0], [3.2], 0.1)
        xy, widths = np.ascontiguousarray(path.xy_m), np.ascontiguousarray(path.lane_width_m)
        blocks = path_blocks(xy)
        for x, y in ((0.0, 0.0), (25.0, 0.0), (math.nan, 1.0), (math.inf, 0.0), (1e300, 0.0)):
            for use_hint, hint, window in (
                (False, 0.0, 0.0),
                (True, 30.0, 200.0),
                (True, 0.0, 0.0),
            ):
                args = (path.spacing_m, path.length_m, use_hint, hint, window, x, y)
                got = project_pruned(xy, blocks, widths, *args)
                want = project_kernel(xy, widths, *args)
                assert got == want or all(
                    a == b or (a != a and b != b) for a, b in zip(got, want, strict=True)
                ), (x, y)
    assert path_blocks(np.array([[0.0, 0.0], [math.nan, 1.0]])).shape == (0, 3)


@settings(max_examples=500, deadline=None)
@given(
    curve=st.lists(st.floats(0.0, 40.0), min_size=1, max_size=400),
    i0=st.integers(0, 420),
    span=st.integers(0, 420),
    spacing=st.floats(0.02, 2.0),
    front_offset=st.floats(0.0, 5.0),
    decel=st.floats(0.1, 9.0),
    v_max=st.one_of(st.floats(0.0, 60.0), st.just(math.inf)),
    nan_at=st.one_of(st.none(), st.integers(0, 399)),
)
def test_pruned_speed_profile_equals_the_full_look_ahead(
    curve, i0, span, spacing, front_offset, decel, v_max, nan_at
):
    speeds = np.asarray(curve, dtype=np.float64)
    if nan_at is not None and nan_at < len(speeds):
        speeds[nan_at] = math.nan
    has_nan = bool(np.isnan(speeds).any())
    i1 = min(len(speeds), i0 + span)
    i0 = min(i0, i1)
    want = profile_speed_kernel(speeds, i0, i1, spacing, front_offset, decel, v_max)
    got = profile_speed_pruned(speeds, i0, i1, spacing, front_offset, decel, v_max, has_nan)
    assert got == want or (math.isnan(got) and math.isnan(want))


# ----------------------------------------------------------------------------- odd values


def _one_observation(**changes: object) -> Observation:
    obs = ALL_LOGS[0].observations[50]
    return dataclasses.replace(obs, **changes)  # type: ignore[arg-type]


def _same_or_both_nan(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


ODD: dict[str, dict[str, float]] = {
    "nan_x": {"x_m": math.nan},
    "inf_y": {"y_m": math.inf},
    "inf_speed": {"speed_mps": math.inf},
    "nan_speed": {"speed_mps": math.nan},
    "nan_length": {"length_m": math.nan},
    "nan_yaw": {"yaw_rad": math.nan},
    "nan_lane_offset": {"lane_offset_m": math.nan},
    "nan_front_offset": {"front_offset_m": math.nan},
}


@pytest.mark.parametrize("name", sorted(ODD))
def test_odd_values_raise_or_step_as_before(name):
    """NaN and infinite observations: where the reference raises, the step raises a
    ValueError naming the state; the rest give the same values (Python's min / max keep
    the first of a NaN pair, as the kernel's do)."""
    params = ALL_LOGS[0].params.fallback
    fast, ref = RouteFollowing(params), ReferenceRouteFollowing(params)
    obs = _one_observation(**ODD[name])
    try:
        want = ref.step(obs)
    except (ValueError, OverflowError):
        with pytest.raises(ValueError, match="non-finite"):
            fast.step(obs)
        return
    got = fast.step(obs)
    assert _same_or_both_nan(got.speed_mps, want.speed_mps)
    assert _same_or_both_nan(got.yaw_rate_radps, want.yaw_rate_radps)
    assert got.lane_change == want.lane_change
    assert _same_or_both_nan(fast._s_m, ref._s_m)


def test_unusual_lane_ids_are_stepped_as_before():
    """A path whose lane ids do not all read as EDGE_INDEX: the lane request runs in
    Python (on the lanes it asks about, which read)."""
    params = ALL_LOGS[0].params.fallback
    pts = np.column_stack([np.linspace(0, 400, 801), np.zeros(801)])
    path = RoutePath.from_pieces(
        [pts[:400], pts[399:]], ["edge_1", "plain"], [13.89] * 2, [3.2] * 2, 0.5,
        [LaneChange(100.0, 110.0, ("edge_2",))],
    )  # fmt: skip
    assert len(path.kernel_arrays[3]) == 0  # lane codes: unreadable, Python lane_step
    fast, ref = RouteFollowing(params), ReferenceRouteFollowing(params)
    requests = 0
    for k in range(60):
        obs = _one_observation(path=path, x_m=40.0 + 2.0 * k, y_m=3.0, yaw_rad=0.0,
                               lane_offset_m=3.2, signal=None)  # fmt: skip
        got = fast.step(obs)
        assert_same(fast, ref, got, ref.step(obs), str(k))
        requests += got.lane_change != 0
    assert requests > 20
