"""The fast ``LaserFollower`` against the numpy implementation it replaced
(``reference_laser_follower.py``, the test oracle): the same commands (speed, yaw rate,
lane request), modes, telemetry, tracks and trails, to 1e-9, step by step.

1. Observations recorded from real closed-loop runs (``observation_log.py``: the urban
   grid platoon, the first platoon of the DRT city with lane actuation, a robot-scale
   laser follower in the paper world) replayed through both, with the recorded
   parameters and variants of them.
2. The scripted closed loops of ``test_laser_follower.py`` run with a twin follower that
   steps the reference beside the fast one on every observation (drives with the fast
   one's commands): lane requests, tracks turning off the route, losses, robots.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

import tests.control.test_laser_follower as scripted
from platoon_sumo.control.base import Command, GapPolicy, Observation
from platoon_sumo.control.laser_follower import LaserFollower, LaserFollowerParams
from platoon_sumo.control.perception import TrackerParams
from tests.control.observation_log import FollowerLog, load, logs
from tests.control.reference_laser_follower import ReferenceLaserFollower

TOL = 1e-9


def assert_same_step(
    fast: LaserFollower, ref: ReferenceLaserFollower, got: Command, want: Command, where: str
) -> None:
    assert fast.mode == ref.mode, where
    assert abs(got.speed_mps - want.speed_mps) < TOL, where
    assert abs(got.yaw_rate_radps - want.yaw_rate_radps) < TOL, where
    assert got.lane_change == want.lane_change, where
    assert (got.heading_rad is None) == (want.heading_rad is None), where
    assert got.telemetry is not None and want.telemetry is not None
    assert got.telemetry.mode == want.telemetry.mode == fast.mode, where
    assert got.telemetry.gap_policy == want.telemetry.gap_policy, where
    gap, ref_gap = got.telemetry.measured_gap_m, want.telemetry.measured_gap_m
    assert (gap is None) == (ref_gap is None), where
    assert gap is None or ref_gap is None or abs(gap - ref_gap) < TOL, where
    track, ref_track = fast.track, ref.track
    assert (track is None) == (ref_track is None), where
    if track is not None and ref_track is not None:
        for f in dataclasses.fields(track):
            a, b = getattr(track, f.name), getattr(ref_track, f.name)
            assert a == b if isinstance(a, bool) else abs(a - b) < TOL, (where, f.name)
    trail, ref_trail = fast.trail, ref.trail
    assert trail.shape == ref_trail.shape, where
    assert trail.size == 0 or abs(trail - ref_trail).max() < TOL, where
    tracker, ref_tracker = fast.tracker, ref.tracker
    assert (tracker.active, tracker.hits, tracker.missed) == (
        ref_tracker.active,
        ref_tracker.hits,
        ref_tracker.missed,
    ), where
    cand, ref_cand = tracker.last_candidate, ref_tracker.last_candidate
    assert (cand is None) == (ref_cand is None), where
    if cand is not None and ref_cand is not None:
        assert abs(cand.x_m - ref_cand.x_m) < TOL and abs(cand.y_m - ref_cand.y_m) < TOL, where
        assert (cand.complete, cand.l_shape, cand.alternative) == (
            ref_cand.complete,
            ref_cand.l_shape,
            ref_cand.alternative,
        ), where
        assert cand.points.shape == ref_cand.points.shape, where


def replay(log: FollowerLog, params: LaserFollowerParams) -> dict[str, int]:
    """Step both on the log; the reference stops wherever lost (``leave_junctions``
    came after it)."""
    fast = LaserFollower(dataclasses.replace(params, leave_junctions=False))
    ref = ReferenceLaserFollower(params)
    modes: dict[str, int] = {}
    for k, obs in enumerate(log.observations):
        got, want = fast.step(obs), ref.step(obs)
        assert_same_step(fast, ref, got, want, f"{log.vehicle_id} step {k} t={obs.time_s:.2f}")
        modes[fast.mode] = modes.get(fast.mode, 0) + 1
    return modes


LOGS = {path.name.removesuffix(".obs.xz"): path for path in logs()}


def test_the_recorded_logs_are_there_and_small():
    assert set(LOGS) == {"urban_platoon", "city_platoons", "robot_world"}
    assert all(path.stat().st_size < 2_000_000 for path in LOGS.values())


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(LOGS))
def test_recorded_runs_replay_identically(name):
    """Each recorded follower with its recorded parameters (in the city, the last
    follower is held at a light and drives on the route-following fallback a while)."""
    modes = [replay(log, log.params) for log in load(LOGS[name])]
    assert all(m.get("following", 0) > 0.8 * sum(m.values()) for m in modes)
    if name == "city_platoons":
        assert modes[-1].get("route_following", 0) > 50


VARIANTS: dict[str, dict[str, Any]] = {
    "route_following": {"on_lost": "route_following"},
    "predecessor": {"steer_at": "predecessor"},
    "no_corridor": {"corridor_half_width_m": None},
    "fixed_corridor": {"corridor_half_width_m": 1.0, "corridor_exit_s": 0.2},
    "constant_distance": {"policy": "constant_distance", "standstill_gap_m": 6.0},
    "short_trail": {"max_trail_points": 3, "trail_spacing_m": 2.0},
    "narrow": {"predecessor_width_m": 1.2, "min_gap_m": 9.0},
    "tight_gate": {
        "on_lost": "route_following",
        "tracker": TrackerParams(gate_chi2=0.3, meas_noise_m=0.01, accel_noise_mps2=0.5),
    },
}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_recorded_run_replays_identically_with_other_parameters(variant):
    """The urban follower's observations with other parameters: other modes, blocked
    stops, trails cut short, tracks dropped by a narrow corridor."""
    log = load(LOGS["urban_platoon"])[0]
    log = dataclasses.replace(log, observations=log.observations[:400])
    replay(log, dataclasses.replace(log.params, **VARIANTS[variant]))


@pytest.mark.parametrize("on_lost", ["stop", "route_following"])
def test_recorded_run_with_scan_outages_replays_identically(on_lost):
    """Scans that see nothing for 2.5 s and 1.2 s: the track is lost (stop or fallback)
    and started again on the predecessor (on the own route, a new trail)."""
    log = load(LOGS["urban_platoon"])[0]

    def blank(obs: Observation) -> Observation:
        assert obs.scan is not None
        empty = np.full_like(obs.scan.ranges, np.inf)
        return dataclasses.replace(obs, scan=dataclasses.replace(obs.scan, ranges=empty))

    observations = [
        blank(obs) if 100 <= k < 125 or 250 <= k < 262 else obs
        for k, obs in enumerate(log.observations[:400])
    ]
    log = dataclasses.replace(log, observations=observations)
    modes = replay(log, dataclasses.replace(log.params, on_lost=on_lost))
    lost = "stopping" if on_lost == "stop" else "route_following"
    assert modes[lost] > 20 and modes["following"] > 300


# ----------------------------------------------------------------------------- scripted


class TwinFollower(LaserFollower):
    """A ``LaserFollower`` that steps the reference beside itself and compares."""

    steps = 0

    def __init__(self, params: LaserFollowerParams | None = None):
        self.reference: ReferenceLaserFollower | None = None
        super().__init__(params)
        self.reference = ReferenceLaserFollower(self.params)

    def reset(self) -> None:
        super().reset()
        if self.reference is not None:
            self.reference.reset()

    def step(self, observation: Observation) -> Command:
        got = super().step(observation)
        assert self.reference is not None
        want = self.reference.step(observation)
        assert_same_step(self, self.reference, got, want, f"t={observation.time_s:.2f}")
        TwinFollower.steps += 1
        return got


class _Request:
    node = type("Node", (), {"user_properties": []})()


SCRIPTED: list[tuple[str, dict[str, Any]]] = [
    ("test_predecessor_straight_ahead_is_tracked_and_followed", {}),
    ("test_offset_predecessor_steers_towards_it", {}),
    ("test_turning_predecessor_keeps_its_rear_centre", {}),
    ("test_partially_occluded_predecessor_is_tracked_at_its_true_rear", {}),
    ("test_absent_predecessor_stops_or_falls_back_to_the_route", {}),
    ("test_too_close_predecessor_brakes_hard_and_very_close_stops", {}),
    ("test_wall_ahead_is_not_taken_for_a_predecessor", {}),
    ("test_stale_scan_is_not_processed_twice_and_reset_forgets", {}),
    ("test_car_hard_brake_to_standstill_no_collision", {}),
    ("test_car_turn_corners_on_the_leaders_line", {"steer_at": "trail", "request": _Request()}),
    (
        "test_car_turn_corners_on_the_leaders_line",
        {"steer_at": "predecessor", "request": _Request()},
    ),
    ("test_robot_scale_speed_steps_and_turn_keep_in_view", {}),
    ("test_predecessor_disappears_then_reappears", {}),
    ("test_car_in_the_neighbouring_lane_is_not_taken_for_a_predecessor", {"corridor": "lane"}),
    ("test_car_in_the_neighbouring_lane_is_not_taken_for_a_predecessor", {"corridor": None}),
    ("test_corridor_follows_the_lane_sumo_drives_in_beside_the_route", {}),
    ("test_predecessor_in_the_next_lane_asks_for_a_lane_change", {"pred_y": 3.3, "lane_change": 1}),
    (
        "test_predecessor_in_the_next_lane_asks_for_a_lane_change",
        {"pred_y": -3.1, "lane_change": -1},
    ),
    ("test_car_in_the_outer_lane_of_a_curve_is_not_taken_for_a_predecessor", {"corridor": "lane"}),
    ("test_predecessor_turning_off_the_route_is_dropped_and_not_followed", {"exit_s": 0.5}),
    ("test_predecessor_turning_off_the_route_is_dropped_and_not_followed", {"exit_s": 1000.0}),
    ("test_robot_predecessor_turning_off_the_route_is_dropped", {}),
]


@pytest.mark.parametrize(
    ("name", "kwargs"),
    SCRIPTED,
    ids=[f"{n.removeprefix('test_')}-{i}" for i, (n, _) in enumerate(SCRIPTED)],
)
def test_scripted_closed_loops_match_the_reference(monkeypatch, name, kwargs):
    monkeypatch.setattr(scripted, "LaserFollower", TwinFollower)
    before = TwinFollower.steps
    getattr(scripted, name)(**kwargs)
    assert TwinFollower.steps > before


def test_telemetry_reports_mode_measured_gap_and_policy():
    log = load(LOGS["urban_platoon"])[0]
    params = dataclasses.replace(log.params, policy="constant_distance", standstill_gap_m=4.0)
    follower = LaserFollower(params)
    commands = [follower.step(obs) for obs in log.observations[:20]]
    telemetry = [c.telemetry for c in commands]
    assert all(t is not None and t.gap_policy == GapPolicy(4.0, 0.0) for t in telemetry)
    assert telemetry[0] is not None and telemetry[0].mode == "stopping"
    assert telemetry[0].measured_gap_m is None
    last = telemetry[-1]
    assert last is not None and last.mode == "following" and last.measured_gap_m is not None
    assert follower.track is not None
    # the straight-line gap from the own bumper to the tracked rear
    obs = log.observations[19]
    c, s = math.cos(obs.yaw_rad), math.sin(obs.yaw_rad)
    bumper = (obs.x_m + obs.front_offset_m * c, obs.y_m + obs.front_offset_m * s)
    assert last.measured_gap_m == pytest.approx(
        math.dist(bumper, (follower.track.x_m, follower.track.y_m)), abs=1e-9
    )
    assert LaserFollower(log.params).gap_policy == GapPolicy(
        log.params.standstill_gap_m, log.params.time_gap_s
    )
