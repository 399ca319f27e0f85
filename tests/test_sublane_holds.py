"""The sublane actuator's sideways checks on a fake SUMO port: a lane change that SUMO
would put down onto another car waits, ours and SUMO's own (a car handed over to SUMO's
lane change), and SUMO's own sideways move into a car beside waits too."""

from __future__ import annotations

import numpy as np

from platoon_sumo.actuation import ActuationBatch, SublaneActuation, Surroundings
from platoon_sumo.vehicles import Bicycle, KinematicState, MotionLimits
from tests.fakes import FakeBackend

CARS = ("ours", "sumos")
LIMITS = MotionLimits(max_speed_mps=15.0, max_accel_mps2=2.0, max_decel_mps2=4.5,
                      max_yaw_rate_radps=1.0)  # fmt: skip


class Port(FakeBackend):
    """Two cars driving along +x at 2 m/s, 4.5 m long with their centres at x 0 and
    y 0 / 10; `sumos` is steered by SUMO at `sumo_mps` sideways; `landing` is where SUMO
    would put down the cars whose move crosses a lane edge (NaN: none)."""

    def __init__(self, sumo_mps: float, landing: np.ndarray) -> None:
        super().__init__()
        self.sumo_mps, self.landing = sumo_mps, landing

    def lane_room(self, vehicle_ids):
        n = len(vehicle_ids)  # centred on 3.2 m lanes, 1 km from their ends
        return np.zeros(n), np.full(n, 0.7), np.full(n, 1000.0)

    def sumo_lateral_speeds(self, vehicle_ids, offset_m):
        return np.array([self.sumo_mps if v == "sumos" else np.nan for v in vehicle_ids])

    def lane_change_landings(self, vehicle_ids, offset_m, lateral_mps, speed_mps, dt_s):
        return self.landing.copy()


def actuate(port: Port, yaw_rate_radps: float, others: list[tuple[float, ...]]) -> Port:
    """Both cars commanded straight on at 2 m/s (`ours` turning at `yaw_rate_radps`)."""
    n = len(CARS)
    state = KinematicState(np.zeros(n), np.array([0.0, 10.0]), np.zeros(n), np.full(n, 2.0))
    rects = np.array([(0.0, 0.0, 0.0, 4.5, 1.8), (0.0, 10.0, 0.0, 4.5, 1.8), *others])
    batch = ActuationBatch(
        vehicle_ids=CARS, state=state, speed_cmd_mps=np.full(n, 2.0),
        yaw_rate_cmd_radps=np.array([yaw_rate_radps, 0.0]), lane_change=np.zeros(n, int),
        front_offset_m=3.5, length_m=4.5, limits=LIMITS, model=Bicycle(),
        dt_s=0.1, surroundings=Surroundings(
            rects, np.full(len(rects), 2.0), np.zeros(len(rects)), np.array([0, 1])
        ),
    )  # fmt: skip
    SublaneActuation().apply(batch, port)
    return port


def test_a_landing_onto_a_car_holds_both_kinds_of_lane_change():
    """Both would land 7 m back, where a car follows each at 2 m/s."""
    landing = np.array([(-7.0, 0.0, 0.0, 4.5, 1.8), (-7.0, 10.0, 0.0, 4.5, 1.8)])
    followers = [(-7.5, 0.0, 0.0, 4.5, 1.8), (-7.5, 10.0, 0.0, 4.5, 1.8)]
    port = actuate(Port(sumo_mps=1.0, landing=landing), 0.3, followers)
    assert port.lateral_speeds["ours"] == 0.0
    assert port.held_lateral == ["sumos"]
    # the same landings with nobody there: both moves go ahead
    port = actuate(Port(sumo_mps=1.0, landing=landing), 0.3, [])
    assert port.lateral_speeds["ours"] > 0.1
    assert port.held_lateral == []


def test_sumos_own_sideways_move_into_a_car_beside_waits():
    """A car 0.3 m clear of the SUMO-steered one's left side: SUMO's move towards it
    waits, one away from it does not."""
    beside = [(0.0, 12.4, 0.0, 4.5, 1.8)]
    nowhere = np.full((2, 5), np.nan)
    assert actuate(Port(sumo_mps=1.0, landing=nowhere), 0.0, beside).held_lateral == ["sumos"]
    assert actuate(Port(sumo_mps=-1.0, landing=nowhere), 0.0, beside).held_lateral == []
