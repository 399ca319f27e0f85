"""Who must stay behind a car that SUMO is to move sideways (`SumoBackend.sideways_waits`),
read from the real SUMO: SUMO moves a car across a lane only with room behind it on
every sublane it enters, and our cars do not make that room by themselves.

The network: edge `ramp` with two 5 m lanes, of which only the left one (1) goes on
to edge `out`, and a junction `J` from a 6 m lane `wide` onto a 3.2 m lane `narrow`."""

from __future__ import annotations

from collections.abc import Iterator

import libsumo
import numpy as np
import pytest

from platoon_sumo.sumo.backend import LANE_CHANGE_REQUESTS_ONLY, SumoBackend, SumoOptions
from platoon_sumo.world import VehicleAhead
from tests.helpers import build_net

NODES = """<nodes><node id="W" x="0" y="0"/><node id="M" x="100" y="0"/>
<node id="E" x="300" y="0"/><node id="S" x="0" y="-100"/><node id="J" x="100" y="-100"/>
<node id="T" x="300" y="-100"/></nodes>"""
EDGES = """<edges><edge id="ramp" from="W" to="M" numLanes="2" speed="13.9" width="5.0"/>
<edge id="out" from="M" to="E" numLanes="1" speed="13.9" width="3.2"/>
<edge id="wide" from="S" to="J" numLanes="1" speed="13.9" width="6.0"/>
<edge id="narrow" from="J" to="T" numLanes="1" speed="13.9" width="3.2"/></edges>"""
CONNECTIONS = """<connections><connection from="ramp" to="out" fromLane="1" toLane="0"/>
</connections>"""


@pytest.fixture
def backend(tmp_path) -> Iterator[SumoBackend]:
    net = build_net(tmp_path, NODES, EDGES, CONNECTIONS, "--no-turnarounds")
    sumo = SumoBackend(SumoOptions(str(net), 0.1, 1, lateral_resolution_m=0.4))
    sumo.start()
    libsumo.route.add("ramp_out", ["ramp", "out"])
    libsumo.route.add("wide_narrow", ["wide", "narrow"])
    try:
        yield sumo
    finally:
        sumo.close()


def standing(vid: str, route: str, lane: int, front_m: float) -> None:
    """A car that stands where it is put and moves sideways only when asked."""
    libsumo.vehicle.add(vid, route, departLane=str(lane), departPos=str(front_m))
    libsumo.vehicle.setSpeed(vid, 0.0)
    libsumo.vehicle.setLaneChangeMode(vid, LANE_CHANGE_REQUESTS_ONLY)


def move_sideways(backend: SumoBackend, offsets_m: dict[str, float]) -> None:
    """Move these cars (inserted) this far sideways from where they are [m] (left +)."""
    for vid, offset in offsets_m.items():
        libsumo.vehicle.setMaxSpeedLat(vid, 10.0)
        libsumo.vehicle.changeSublane(vid, offset)
    for _ in range(30):
        backend.step()


def test_cars_behind_a_lane_change_waiting_across_their_path_are_held(backend):
    standing("changer", "ramp_out", 0, 90.0)  # on the lane that ends: must go left
    standing("behind_left", "ramp_out", 1, 80.0)  # in the target lane, 5 m behind its back
    standing("behind_same", "ramp_out", 0, 60.0)  # behind it on its own lane
    standing("level", "ramp_out", 1, 88.0)  # beside: its front past the changer's back
    standing("far_left", "ramp_out", 1, 70.0)
    backend.step()
    move_sideways(backend, {"far_left": 1.5})  # beside the band: left of lane 1's centre
    # slow near the end of a lane its route leaves: SUMO makes its lane change
    backend.set_lateral_speeds(["changer"], np.zeros(1))
    others = ["behind_left", "behind_same", "level", "far_left"]
    assert libsumo.vehicle.getLateralLanePosition("far_left") > 1.0  # as put there
    waits = backend.sideways_waits(others, [None] * len(others))
    length = libsumo.vehicle.getLength("changer")
    assert set(waits) == {"behind_left", "behind_same"}
    assert waits["behind_left"] == ("changer", pytest.approx(90.0 - length - 80.0))
    assert waits["behind_same"] == ("changer", pytest.approx(90.0 - length - 60.0))


def test_a_car_inside_a_junction_beside_its_next_lane_holds_the_car_behind(backend):
    standing("misfit", "wide_narrow", 0, 97.0)
    backend.step()
    move_sideways(backend, {"misfit": -2.0})  # 2 m right of the wide lane's centre
    # SUMO drives it into the junction without centring it (lane-change mode 0)
    libsumo.vehicle.setSpeed("misfit", 3.0)
    for _ in range(40):
        backend.step()
        if libsumo.vehicle.getLaneID("misfit").startswith(":"):
            break
    behind = VehicleAhead("misfit", 3.0, 0.0)
    assert libsumo.vehicle.getSpeed("misfit") > 1.0  # moving: it will stop at the exit
    assert backend.sideways_waits(["follower"], [behind]) == {"follower": ("misfit", 3.0)}
    libsumo.vehicle.setSpeed("misfit", 0.0)
    for _ in range(10):
        backend.step()
    lane = libsumo.vehicle.getLaneID("misfit")
    assert lane.startswith(":") and libsumo.vehicle.getLateralLanePosition("misfit") < -1.0
    assert backend.sideways_waits(["follower"], [behind]) == {"follower": ("misfit", 3.0)}
    level = VehicleAhead("misfit", -0.5, 0.0)  # level with its back: drives on, not held
    assert backend.sideways_waits(["follower"], [level]) == {}
    libsumo.vehicle.changeSublane("misfit", 2.0)  # centred: fits the narrow lane
    for _ in range(40):
        backend.step()
    assert abs(libsumo.vehicle.getLateralLanePosition("misfit")) < 0.5
    assert backend.sideways_waits(["follower"], [behind]) == {}


def test_a_car_handed_to_sumos_lane_change_is_steered_by_us_inside_a_junction(backend):
    """SUMO does not fit the body of a car it moves into the lane after a junction; our
    steering does (`actuation.fit_ahead`), so a car handed over is given back there."""
    standing("changer", "ramp_out", 0, 90.0)
    backend.step()
    veh = libsumo.vehicle
    handed = []
    for _ in range(200):
        backend.set_lateral_speeds(["changer"], np.zeros(1))
        handed.append(veh.getLaneChangeMode("changer") != LANE_CHANGE_REQUESTS_ONLY)
        if veh.getLaneID("changer") == "ramp_1":
            veh.setSpeed("changer", 3.0)  # on into the junction
        backend.step()
        if veh.getLaneID("changer").startswith(":"):
            break
    assert handed[0] and veh.getLaneID("changer").startswith(":")
    backend.set_lateral_speeds(["changer"], np.zeros(1))
    assert veh.getLaneChangeMode("changer") == LANE_CHANGE_REQUESTS_ONLY
    assert np.isnan(backend.sumo_lateral_speeds(["changer"], np.zeros(1))).all()


def test_a_car_beside_is_no_leader(backend, monkeypatch: pytest.MonkeyPatch):
    """SUMO's leader in the sublane model may be a car beside, with a negative gap (on
    the race circuit, a car that had overtaken a platoon car on the right inside a
    junction, standing with its body beside the narrower lane after it): followed as a
    leader, it held the platoon car for good, in the way of that car's move back."""
    standing("ahead", "ramp_out", 1, 60.0)
    standing("behind", "ramp_out", 1, 50.0)
    backend.step()
    ahead = backend.vehicle_ahead("behind", 100.0)
    assert ahead is not None and ahead.vehicle_id == "ahead"
    assert ahead.gap_m == pytest.approx(60.0 - veh_length("ahead") - 50.0)
    min_gap = libsumo.vehicle.getMinGap("behind")
    # SUMO's answer for a car whose back is level with the front bumper, 0.1 m beyond
    monkeypatch.setattr(libsumo.vehicle, "getLeader", lambda *_: ("ahead", -min_gap - 0.1))
    assert backend.vehicle_ahead("behind", 100.0) is None


def veh_length(vid: str) -> float:
    return float(libsumo.vehicle.getLength(vid))
