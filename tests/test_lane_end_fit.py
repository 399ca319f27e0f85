"""Sublane actuation near the end of a lane (`platoon_sumo.actuation.fit_at_lane_end`):
a car that will reach its lane's end within `LANE_END_FIT_S` gets there with its body
inside the lane (SUMO lets it onto the next lane only so); earlier, its sideways move is
the controller's."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.actuation import LANE_END_FIT_MPS, LANE_END_FIT_S, fit_at_lane_end
from platoon_sumo.sumo import backend

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


class _Lanes:
    """libsumo's lane domain for `SumoBackend._exit_room`: a junction lane ending
    eastwards into a lane that starts 141 degrees off (the race circuit's invented ramp),
    and an edge's lane with a 120-degree turn among its links."""

    def __init__(self) -> None:
        self.shapes = {
            ":J_0_0": [(-10.0, 0.0), (0.0, 0.0)],
            "out_0": [(0.0, 0.0), (10 * math.cos(2.461), 10 * math.sin(2.461))],
            "in_0": [(-50.0, 0.0), (-10.0, 0.0)],
        }
        self.links = {
            ":J_0_0": [("out_0", 1, 1, 0, "", "G")],
            "in_0": [("out_0", 1, 1, 0, ":J_0_0", "G")],
        }

    def getWidth(self, lane: str) -> float:
        return 3.2

    def getLinks(self, lane: str) -> list[tuple]:
        return self.links.get(lane, [])

    def getShape(self, lane: str) -> list[tuple[float, float]]:
        return self.shapes[lane]

    def getLength(self, lane: str) -> float:
        (x0, y0), (x1, y1) = self.shapes[lane]
        return math.hypot(x1 - x0, y1 - y0)


def test_a_junction_lane_that_meets_the_next_at_an_angle_is_left_near_its_centre():
    """SUMO moves a sublane car onto the next lane at its offset from the centre: where
    a junction's lane meets the next at 141 degrees (the race circuit, seed 45), a car
    d beside the centre lands 2 d sin(70.5 degrees) away, and it leaves the lane within
    the offset that moves it `EXIT_JUMP_M`. An edge's lane is bounded by the widths
    only: its links are every turn, not the one the car takes."""
    sumo = backend.SumoBackend(backend.SumoOptions("unused.net.xml", 0.1, 1))
    sumo._api = SimpleNamespace(lane=_Lanes())  # type: ignore[assignment]
    width, max_offset = sumo._exit_room(":J_0_0")
    turn = math.pi - 2.461  # between east and the next lane's start
    assert width == 3.2
    assert max_offset == pytest.approx(backend.EXIT_JUMP_M / (2 * math.sin(0.5 * (math.pi - turn))))
    assert sumo._exit_room("in_0") == (3.2, math.inf)
