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
