"""The lane-change gap stage (loop.lane_change) alone, on a hand-made member and lanes."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from platoon_sumo.loop.lane_change import LaneChangeGaps
from platoon_sumo.path import LaneChange

LENGTH_M = 4.5
#: The route's change: path arc length 70-120 m, beginning 20 m along the target lane.
CHANGE = LaneChange(70.0, 120.0, ("ramp_3",), begin_lane_pos_m=20.0)


def member_during_the_change(occupants: list[tuple[str, float, float, float]]):
    """A steered member 34.8 m into the path's change stretch (its front, reckoned along
    the target lane from the path, at 54.8 m), and a backend whose target lane holds
    `occupants` (id, front position, speed, length)."""
    path = SimpleNamespace(
        next_lane_change=lambda s: CHANGE,
        xy_m=np.column_stack([np.arange(0.0, 201.0), np.zeros(201)]),
        spacing_m=1.0,
    )
    vehicle = SimpleNamespace(length_m=LENGTH_M, width_m=1.8)
    member = SimpleNamespace(
        id="p.3", path=path, route_s_m=104.8, speed_mps=0.0, lane_change=None,
        actuator=SimpleNamespace(steers=True),
        platoon=SimpleNamespace(config=SimpleNamespace(vehicle=vehicle)),
    )  # fmt: skip
    backend = SimpleNamespace(lane_occupants=lambda lane: occupants if lane == "ramp_3" else [])
    ctx = SimpleNamespace(fleet=[member], backend=backend, world=SimpleNamespace(index={}))
    return ctx, member


def test_a_member_is_not_its_own_leader_in_the_target_lane():
    # osm_spreewaldring: SUMO made a steep shift for the car (the hand-over) and the car
    # stood on the target lane with its rear 0.4 m ahead of where the path placed its
    # front (the path cuts across the curve's lanes, the outer lane is longer): it was
    # its own target-lane leader, the emergency brake held it at 0 for good, and 8
    # platoon cars queued behind it
    ctx, member = member_during_the_change([("p.3", 59.7, 0.0, LENGTH_M)])
    LaneChangeGaps()(ctx)  # type: ignore[arg-type]
    assert member.lane_change is not None and member.lane_change.clear
    assert member.lane_change.target_leader is None


def test_the_vehicle_ahead_in_the_target_lane_is_still_its_leader():
    ctx, member = member_during_the_change(
        [("p.3", 59.7, 0.0, LENGTH_M), ("bg1", 80.0, 3.0, LENGTH_M)]
    )
    LaneChangeGaps()(ctx)  # type: ignore[arg-type]
    leader = member.lane_change.target_leader
    assert leader is not None and leader.vehicle_id == "bg1"
    assert abs(leader.gap_m - (80.0 - LENGTH_M - 54.8)) < 1e-9


def test_a_member_already_in_its_last_target_lane_waits_for_no_car_it_has_passed_over():
    """osm_spreewaldring: the route crosses two 10 m lanes of netconvert's on-ramp; a
    follower, there before its path (SUMO made the change for it), stood on the last
    target lane for good, held by a car on a lane it had crossed, alongside the path it
    no longer drove on; 10 of 12 platoon cars never arrived."""
    two_lanes = LaneChange(70.0, 120.0, ("ramp_2", "ramp_3"), begin_lane_pos_m=20.0)
    beside = [("bg2", 55.0, 0.0, LENGTH_M)]  # on ramp_2, alongside, where the path runs
    held = {}
    for here in ("ramp_1", "ramp_3"):
        ctx, member = member_during_the_change([])
        member.path.next_lane_change = lambda s: two_lanes
        ctx.backend = SimpleNamespace(
            lane_occupants=lambda lane: beside if lane == "ramp_2" else [],
            lane_shape=lambda lane: np.array([[0.0, 0.0], [200.0, 0.0]]),
            lane_width=lambda lane: 3.2,
        )
        ctx.world = SimpleNamespace(
            index={"p.3": 0, "bg2": 1}, lane_ids=[here, "ramp_2"],
            front_x_m=np.array([104.8, 105.0]), front_y_m=np.array([0.0, 0.0]),
            width_m=np.array([1.8, 1.8]),
        )  # fmt: skip
        LaneChangeGaps()(ctx)  # type: ignore[arg-type]
        held[here] = not member.lane_change.clear
    assert held == {"ramp_1": True, "ramp_3": False}
