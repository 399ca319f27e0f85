"""Sublane actuation near the end of a lane (`platoon_sumo.actuation.fit_at_lane_end`):
a car that will reach its lane's end within `LANE_END_FIT_S` gets there with its body
inside the lane (SUMO lets it onto the next lane only so); earlier, its sideways move is
the controller's."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.actuation import LANE_END_FIT_MPS, LANE_END_FIT_S, fit_at_lane_end

DT = 0.1
cars = st.tuples(
    st.floats(-3.0, 3.0),  # lateral speed asked for [m/s]
    st.floats(-2.5, 2.5),  # offset from the lane's centre [m]
    st.floats(0.0, 1.5),  # room either side [m]
    st.floats(0.0, 200.0),  # to the lane's end [m]
    st.floats(0.0, 30.0),  # speed [m/s]
)


def fit(lateral, offset, room, to_end, speed):
    a = [np.array([v], dtype=np.float64) for v in (lateral, offset, room, to_end, speed)]
    return float(fit_at_lane_end(a[0], a[1], a[2], a[3], a[4], DT)[0])


@settings(max_examples=300, deadline=None)
@given(car=cars)
def test_a_car_inside_its_room_stays_inside_at_the_lane_end(car):
    lateral, offset, room, to_end, speed = car
    left_s = max(to_end / max(speed, 1e-3), DT)
    u = fit(lateral, np.clip(offset, -room, room), room, to_end, speed)
    if left_s > LANE_END_FIT_S:
        assert u == lateral  # far from the end: the controller's move, untouched
    else:
        assert abs(np.clip(offset, -room, room) + u * left_s) <= room + 1e-9


@settings(max_examples=300, deadline=None)
@given(car=cars)
def test_a_car_outside_its_room_moves_back_no_faster_than_needed(car):
    lateral, offset, room, to_end, speed = car
    left_s = max(to_end / max(speed, 1e-3), DT)
    u = fit(lateral, offset, room, to_end, speed)
    assert abs(u) <= max(abs(lateral), LANE_END_FIT_MPS) + 1e-12
    if left_s <= LANE_END_FIT_S and abs(offset) > room + 1e-6:
        assert np.sign(u) == -np.sign(offset)  # back towards the lane's centre
        # as far as it may go within the time left, and not beyond the room's far side
        assert abs(offset + u * left_s) <= max(abs(offset) - LANE_END_FIT_MPS * left_s, room) + 1e-9


def test_a_car_standing_at_a_junctions_exit_beside_its_lane_moves_back():
    """Held at the end of a junction's lane 1.48 m beside its centre (seed 44 of the
    `highway` network), standing: it moves back at `LANE_END_FIT_MPS`."""
    assert fit(0.0, -1.48, 0.7, 0.0, 0.0) == LANE_END_FIT_MPS
