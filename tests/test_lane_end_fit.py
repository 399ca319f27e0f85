"""Sublane actuation near the end of a lane or a sharp bend (`platoon_sumo.actuation.
fit_ahead`): a car that will get there soon arrives with its offset within the room it
has there (SUMO lets it onto the next lane only with its body inside it, and jumps it
along the road at a bend); earlier, its sideways move is the controller's. Soon is
`FIT_AHEAD_S`, or longer where moving back at `FIT_LATERAL_MPS` takes longer."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.actuation import FIT_AHEAD_S, FIT_LATERAL_MPS, FIT_RAMP_S, fit_ahead

DT = 0.1
ACCEL = 2.6  # the car's largest acceleration [m/s^2]
cars = st.tuples(
    st.floats(-3.0, 3.0),  # lateral speed asked for [m/s]
    st.floats(-2.5, 2.5),  # offset from the lane's centre [m]
    st.floats(0.0, 1.5),  # room either side [m]
    st.floats(0.0, 200.0),  # to the lane's end or the bend [m]
    st.floats(0.0, 30.0),  # speed [m/s]
)


def fit(lateral, offset, room, to_end, speed, accel=ACCEL):
    a = [np.array([v], dtype=np.float64) for v in (lateral, offset, room, to_end, speed)]
    return float(fit_ahead(a[0], a[1], a[2], a[3], a[4], accel, DT)[0])


def time_left(to_m: float, speed: float, accel: float) -> float:
    """The soonest the car can get there, speeding up at `accel` (solved by bisection:
    an oracle independent of the closed form; at least 1 mm/s) [s], at least one step."""
    lo, hi = 0.0, 1e6
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        reach = max(speed, 1e-3) * mid if accel == 0.0 else speed * mid + 0.5 * accel * mid * mid
        lo, hi = (mid, hi) if reach < to_m else (lo, mid)
    return max(hi, DT)


ACCELS = st.sampled_from([0.0, ACCEL])  # at a lane's end, at a bend


@settings(max_examples=300, deadline=None)
@given(car=cars, accel=ACCELS)
def test_a_car_inside_its_room_stays_inside_when_it_gets_there(car, accel):
    lateral, offset, room, to_end, speed = car
    left_s = time_left(to_end, speed, accel)
    u = fit(lateral, np.clip(offset, -room, room), room, to_end, speed, accel)
    if left_s > FIT_AHEAD_S:
        assert u == lateral  # far from the end: the controller's move, untouched
    else:
        assert abs(np.clip(offset, -room, room) + u * left_s) <= room + 1e-6


@settings(max_examples=300, deadline=None)
@given(car=cars, accel=ACCELS)
def test_a_car_outside_its_room_moves_back_no_faster_than_needed(car, accel):
    lateral, offset, room, to_end, speed = car
    left_s = time_left(to_end, speed, accel)
    u = fit(lateral, offset, room, to_end, speed, accel)
    assert abs(u) <= max(abs(lateral), FIT_LATERAL_MPS) + 1e-12
    window_s = max(FIT_AHEAD_S, (abs(offset) - room) / FIT_LATERAL_MPS + FIT_RAMP_S)
    if left_s > window_s:
        assert u == lateral
    elif abs(offset) > room + 1e-6:
        assert np.sign(u) == -np.sign(offset)  # back towards the lane's centre
        # as far as it may go within the time left, and not beyond the room's far side
        assert abs(offset + u * left_s) <= max(abs(offset) - FIT_LATERAL_MPS * left_s, room) + 1e-6


def test_a_car_standing_at_a_junctions_exit_beside_its_lane_moves_back():
    """Held at the end of a junction's lane 1.48 m beside its centre (seed 44 of the
    `highway` network), standing: it moves back at `FIT_LATERAL_MPS`."""
    assert fit(0.0, -1.48, 0.7, 0.0, 0.0, accel=0.0) == FIT_LATERAL_MPS


@settings(max_examples=200, deadline=None)
@given(
    offset=st.floats(-4.5, 4.5), room=st.floats(0.1, 1.5), speed=st.floats(0.0, 30.0),
    far_s=st.floats(0.0, 5.0), speeding_up=st.booleans(), accel=ACCELS,
)  # fmt: skip
def test_a_car_far_beside_its_room_gets_into_it_with_sumos_lateral_acceleration(
    offset, room, speed, far_s, speeding_up, accel
):
    """Oracle: a car held by its controller where it is (asked 0), whose lateral speed
    follows the one allowed at SUMO's default lateral acceleration of 1 m/s^2, driving
    on at `speed` (or, at a bend, speeding up at `ACCEL` from it, a standing car driving
    off) from `far_s` before the fit starts; it gets to the point within its room (to
    5 cm, one step of the ramp)."""
    speeding_up = speeding_up and accel > 0.0
    speed = speed if speeding_up else max(speed, 1.0)
    window_s = max(FIT_AHEAD_S, (abs(offset) - room) / FIT_LATERAL_MPS + FIT_RAMP_S)
    to_m, lateral = speed * (window_s + far_s) + 0.5 * ACCEL * window_s**2, 0.0
    while to_m > 0.0:
        asked = fit(0.0, offset, room, to_m, speed, accel)
        lateral += float(np.clip(asked - lateral, -DT, DT))  # 1 m/s^2
        offset += lateral * DT
        to_m -= speed * DT + (0.5 * ACCEL * DT * DT if speeding_up else 0.0)
        speed += ACCEL * DT if speeding_up else 0.0
    assert abs(offset) <= room + 0.05
