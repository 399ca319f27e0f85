"""Where cars moving inside a junction will be (`loop.obstacles.moving_footprints`), and
cars about to enter one (`entering_footprints`), against shapely's interpolation along
SUMO's lane shapes (read with sumolib)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sumolib
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString

from platoon_sumo.loop.obstacles import (
    AHEAD_FRACTIONS,
    AHEAD_S,
    JunctionLanes,
    entering_footprints,
    entry_stop_m,
    moving_footprints,
)
from platoon_sumo.sumo.network import Network
from platoon_sumo.world import WorldSnapshot
from tests.helpers import URBAN_GRID_NET

LANES = JunctionLanes(Network(URBAN_GRID_NET))
SUMOLIB = sumolib.net.readNet(str(URBAN_GRID_NET), withInternal=True)
#: A left turn's two junction lanes (to its waiting point, then curved), a right turn
#: inside junction B1, and a normal lane.
LEFT_TURN_START, LEFT_TURN, RIGHT_TURN, ROAD = ":B1_3_0", ":B1_16_0", ":B1_0_0", "A1B1_0"
LENGTH_M, WIDTH_M, DT_S = 4.5, 1.8, 0.1


def snapshot(time_s: float, cars: list[tuple[str, str, float, float]]) -> WorldSnapshot:
    """Cars (id, lane, position along the lane [m], speed [m/s]), fronts on the lane."""
    fronts = [lane_line(lane).interpolate(s) for _, lane, s, _ in cars]
    n = len(cars)
    return WorldSnapshot(
        time_s=time_s,
        ids=tuple(c[0] for c in cars),
        front_x_m=np.array([p.x for p in fronts]),
        front_y_m=np.array([p.y for p in fronts]),
        yaw_rad=np.zeros(n),
        length_m=np.full(n, LENGTH_M),
        width_m=np.full(n, WIDTH_M),
        speed_mps=np.array([c[3] for c in cars], dtype=float),
        lane_ids=tuple(c[1] for c in cars),
        index={c[0]: k for k, c in enumerate(cars)},
    )


def lane_line(lane_id: str) -> LineString:
    return LineString(SUMOLIB.getLane(lane_id).getShape())


def chain_line(lane_id: str) -> LineString:
    """The lane and, from a junction lane, the lanes it leads to up to the next road."""
    points = list(SUMOLIB.getLane(lane_id).getShape())
    while lane_id.startswith(":"):
        (link,) = SUMOLIB.getLane(lane_id).getOutgoing()
        lane_id = link.getViaLaneID() or link.getToLane().getID()
        points += list(SUMOLIB.getLane(lane_id).getShape())[1:]
    return LineString(points)


def front_of(rect: np.ndarray) -> np.ndarray:
    return rect[:2] + 0.5 * rect[3] * np.array([math.cos(rect[2]), math.sin(rect[2])])


@settings(max_examples=200, deadline=None)
@given(
    lane=st.sampled_from([LEFT_TURN_START, LEFT_TURN, RIGHT_TURN]),
    fraction=st.floats(0.0, 1.0),
    speed=st.floats(0.3, 15.0),
    decel=st.floats(-3.0, 8.0),
)
def test_a_car_in_a_junction_is_moved_along_its_lanes(lane, fraction, speed, decel):
    s = fraction * lane_line(lane).length
    line = chain_line(lane)  # on into the lanes it leads to
    now = snapshot(10.0, [("h", lane, s, speed)])
    before = snapshot(10.0 - DT_S, [("h", lane, s, speed + decel * DT_S)])
    near = np.array([[now.front_x_m[0], now.front_y_m[0]]])
    rects, owners, stands = moving_footprints(now, before, LANES, near, 100.0)
    step_s = now.time_s - before.time_s
    shown = max((before.speed_mps[0] - speed) / step_s, 0.0)  # deceleration over the step
    assert owners.tolist() == [0] * len(AHEAD_FRACTIONS)
    for rect, standing, fraction_s in zip(rects, stands, AHEAD_FRACTIONS, strict=True):
        t = fraction_s * AHEAD_S
        stopped = speed <= shown * t  # it has stopped by then
        ahead = speed * speed / (2 * shown) if stopped else speed * t - shown / 2 * t**2
        # both ends on the lanes (shapely counts a negative distance from the end)
        front = line.interpolate(min(s + ahead, line.length))
        rear = line.interpolate(min(max(s + ahead - LENGTH_M, 0.0), line.length))
        assert standing == stopped
        assert front_of(rect) == pytest.approx([front.x, front.y], abs=1e-6)
        if front.distance(rear) > 0.1:  # the body along the lane's chord
            chord = math.atan2(front.y - rear.y, front.x - rear.x)
            assert math.cos(rect[2] - chord) == pytest.approx(1.0, abs=1e-9)
        assert rect[3:].tolist() == [LENGTH_M, WIDTH_M]


def test_only_moving_cars_inside_a_junction_near_a_member_are_moved():
    cars = [
        ("road", ROAD, 50.0, 10.0),  # on a normal lane
        ("standing", LEFT_TURN, 3.0, 0.0),
        ("turning", RIGHT_TURN, 2.0, 5.0),
    ]
    now = snapshot(10.0, cars)
    turning = np.array([[now.front_x_m[2], now.front_y_m[2]]])
    rects, owners, _ = moving_footprints(now, None, LANES, turning + 5.0, 10.0)
    assert set(owners.tolist()) == {2}  # without an earlier world: at its speed
    assert front_of(rects[-1]) == pytest.approx(
        [lane_line(RIGHT_TURN).interpolate(2.0 + 5.0 * AHEAD_S).x,
         lane_line(RIGHT_TURN).interpolate(2.0 + 5.0 * AHEAD_S).y], abs=1e-6,
    )  # fmt: skip
    far = turning + 200.0
    assert len(moving_footprints(now, None, LANES, far, 10.0)[0]) == 0


#: The junction lanes the road's lane leads to (its links' internal lanes).
ROAD_ENTRIES = sorted(c.getViaLaneID() for c in SUMOLIB.getLane(ROAD).getOutgoing())


@settings(max_examples=200, deadline=None)
@given(
    entry=st.sampled_from(ROAD_ENTRIES),
    to_end=st.floats(0.0, 15.0),
    speed=st.floats(0.3, 15.0),
)
def test_a_car_entering_a_junction_is_seen_only_past_its_lanes_end(entry, to_end, speed):
    # the shape's length and a projection on it: a car exactly at the end is either
    assume(all(abs(speed * f * AHEAD_S - to_end) > 1e-6 for f in AHEAD_FRACTIONS))
    road = lane_line(ROAD)
    s = road.length - to_end
    line = LineString(list(road.coords) + list(chain_line(entry).coords)[1:])
    now = snapshot(10.0, [("h", ROAD, s, speed)])
    row = LANES.index(ROAD, entry)
    rects, which, stands = entering_footprints(now, None, LANES, np.array([0]), np.array([row]))
    past = [f for f in AHEAD_FRACTIONS if speed * f * AHEAD_S > to_end]
    assert which.tolist() == [0] * len(past)
    assert not stands.any()  # without an earlier world: at its speed
    for rect, fraction_s in zip(rects, past, strict=True):
        front = line.interpolate(min(s + speed * fraction_s * AHEAD_S, line.length))
        assert front_of(rect) == pytest.approx([front.x, front.y], abs=1e-6)


def test_a_junction_lane_is_measured_to_the_road_it_leads_to():
    """A left turn made of two junction lanes (to its waiting point, then curved)."""
    row = LANES.index(LEFT_TURN_START)
    both = SUMOLIB.getLane(LEFT_TURN_START).getLength() + SUMOLIB.getLane(LEFT_TURN).getLength()
    assert LANES.length_to_exit(row) == pytest.approx(both, rel=1e-3)
    assert LANES.length_to_exit(LANES.index(ROAD)) == 0.0


@given(
    to_line=st.floats(0.0, 50.0),
    junction=st.floats(1.0, 40.0),
    other=st.floats(2.0, 18.0),
    min_gap=st.floats(0.5, 3.0),
)
def test_a_member_waits_at_the_line_at_the_latest_or_goes_first(to_line, junction, other, min_gap):
    """Into one junction lane: where the other car's back, standing at the lane's end,
    leaves the member its minGap, if that is ahead of the member; into another: at the
    line."""
    back = to_line + junction - other  # the other's back, standing at the end
    stop = entry_stop_m(to_line, junction, other, min_gap, same=True)
    if back - min_gap < 0.0:
        assert stop is None
    else:
        assert stop == pytest.approx(min(back - min_gap, to_line))
        assert stop <= to_line
    assert entry_stop_m(to_line, junction, other, min_gap, same=False) == to_line
