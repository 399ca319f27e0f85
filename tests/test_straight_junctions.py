"""Straight movements through junctions on real networks: where SUMO moves the car along
its lanes, the bends a junction's shape gives a straight-through lane do not slow route
following; turns keep their curve speed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from platoon_sumo.control.base import Observation
from platoon_sumo.control.route_following import RouteFollowing, RouteFollowingParams
from platoon_sumo.path import RoutePath
from platoon_sumo.sumo.backend import resolve_sumo_path
from platoon_sumo.sumo.network import Network
from platoon_sumo.vehicles import MotionLimits
from tests.helpers import URBAN_GRID_NET

#: eclipse-sumo's motorway network: at junction 1658939360 lane 0 jogs 4.8 m sideways
#: within 0.3 m (a straight connection, netconvert's direction "s").
HIGHWAY = "sumo:tools/game/highway/highway.net.xml"
JOG = ":1658939360_0_0"
LIMITS = MotionLimits(
    max_speed_mps=15.0, max_accel_mps2=2.5, max_decel_mps2=7.5, max_yaw_rate_radps=1.0,
    max_steer_rad=0.6, wheelbase_m=2.7,
)  # fmt: skip
FRONT_OFFSET_M = 3.6


@pytest.fixture(scope="module")
def motorway() -> RoutePath:
    net = Network(resolve_sumo_path(HIGHWAY))
    return net.route_path(["191842213", "153177809"], spacing_m=0.5, first_lane=0)


def _points_on(path: RoutePath, lane_id: str) -> np.ndarray:
    return np.flatnonzero(path.lane_index == path.lane_ids.index(lane_id))


def test_the_jog_is_a_straight_junction_lane_and_only_its_bends_are_left_out(motorway):
    assert motorway.straight_junction_lanes == frozenset({JOG})
    every = motorway.curvature_1pm(3.0)
    straight_only = motorway.curvature_1pm(3.0, straight_junctions=False)
    jog = _points_on(motorway, JOG)
    near = np.arange(jog[0] - 8, jog[-1] + 9)  # the jog and the smoothing window around it
    assert every[near].max() > 0.4  # two corners of about 88 degrees
    assert straight_only[near].max() < 0.02
    far = np.setdiff1d(np.arange(len(every)), near)
    np.testing.assert_array_equal(every[far], straight_only[far])


def _command_before_jog(path: RoutePath, ahead_m: float, on_sumo_lanes: bool) -> float:
    """Route following's speed command to a car at 11 m/s driving along the lane from
    the route's start until its front is `ahead_m` before the jog."""
    controller = RouteFollowing(RouteFollowingParams(cruise_speed_mps=11.0))
    end = _points_on(path, JOG)[0] * path.spacing_m - ahead_m
    speed = 0.0
    for s_front in np.arange(end - 800.0, end + 1e-9, 1.1):
        fx, fy = path.point_at(s_front)
        yaw = path.heading_at(s_front)
        x, y = fx - FRONT_OFFSET_M * math.cos(yaw), fy - FRONT_OFFSET_M * math.sin(yaw)
        obs = Observation(
            time_s=0.0, dt_s=0.1, vehicle_id="car", role="leader", x_m=x, y_m=y,
            yaw_rad=yaw, speed_mps=11.0, front_offset_m=FRONT_OFFSET_M, length_m=4.5,
            width_m=1.8, limits=LIMITS, path=path, on_sumo_lanes=on_sumo_lanes,
        )  # fmt: skip
        speed = controller.step(obs).speed_mps
    return speed


def test_a_car_sumo_moves_keeps_its_speed_through_a_straight_junction_jog(motorway):
    """Found on `highway` (seed 42): platoons crawled through the jog at 1.9 m/s where
    SUMO's cars passed at 41 m/s, and a follower's body, at SUMO's angle across the
    jog, was struck from the next lane."""
    assert _command_before_jog(motorway, 10.0, on_sumo_lanes=True) == pytest.approx(11.0)
    # our vehicle model drives the polyline itself (planar): it brakes for the corners
    assert _command_before_jog(motorway, 10.0, on_sumo_lanes=False) < 8.0


def test_turns_keep_their_curve_speed():
    grid = Network(URBAN_GRID_NET)
    path = grid.route_path(
        ["left0A0", "A0B0", "B0B1", "B1B2", "B2C2", "C2right2"], spacing_m=0.5, first_lane=0
    )
    junction_lanes = {lane for lane in path.lane_ids if lane.startswith(":")}
    turns = junction_lanes - path.straight_junction_lanes
    assert turns and path.straight_junction_lanes  # the route turns and goes straight on
    every = path.curvature_1pm(3.0)
    straight_only = path.curvature_1pm(3.0, straight_junctions=False)
    at_turns = np.concatenate([_points_on(path, lane) for lane in turns])
    assert every[at_turns].max() > 0.2
    np.testing.assert_array_equal(every[at_turns], straight_only[at_turns])
