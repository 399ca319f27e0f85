"""Route paths built from a real SUMO network (sumolib, no simulation)."""

from __future__ import annotations

import numpy as np
import pytest

from platoon_sumo.sumo.network import Network, RouteError
from tests.helpers import URBAN_GRID_NET, build_net

CROSS_TOWN = ["left0A0", "A0B0", "B0B1", "B1B2", "B2C2", "C2right2"]


@pytest.fixture(scope="module")
def grid() -> Network:
    return Network(URBAN_GRID_NET)


def test_path_is_continuous_and_spans_the_route(grid):
    path = grid.route_path(CROSS_TOWN, spacing_m=0.5, first_lane=0)
    steps = np.hypot(*np.diff(path.xy_m, axis=0).T)
    assert steps.max() <= 0.5 + 1e-9
    edge_lengths = sum(grid.edge_length_m(e) for e in CROSS_TOWN)
    assert edge_lengths < path.length_m < edge_lengths + 5 * 40  # plus 5 junction crossings


def test_left_turn_is_driven_from_the_left_lane(grid):
    # In urban_grid left turns leave from lane 1, right turns from lane 0.
    path = grid.route_path(CROSS_TOWN, spacing_m=0.5, first_lane=0)
    lanes = list(dict.fromkeys(path.lane_ids))
    b0 = [lane for lane in lanes if lane.startswith(":B0_")]
    assert b0, "the path crosses junction B0 through its internal lanes"
    # Where the path enters junction B0 it is at the end of A0B0's left lane (lane 1).
    entry = path.xy_m[np.flatnonzero(path.lane_index == path.lane_ids.index(b0[0]))[0]]
    assert np.hypot(*(entry - grid.lane_shape("A0B0_1")[-1])) < 0.5
    # and it departed on the right lane (lane 0) as asked
    assert np.hypot(*(path.xy_m[0] - grid.lane_shape("left0A0_0")[0])) < 1e-6


def test_unknown_and_unconnected_edges_are_route_errors(grid):
    with pytest.raises(RouteError, match="unknown edge 'A0B9'") as unknown:
        grid.check_edges(["left0A0", "A0B9"])
    assert unknown.value.index == 1
    with pytest.raises(RouteError, match="does not connect") as unconnected:
        grid.check_edges(["left0A0", "B1B2"])
    assert unconnected.value.index == 1


def test_shortest_route_connects_from_and_to(grid):
    edges = grid.shortest_route("left0A0", "C2right2")
    grid.check_edges(edges)
    assert edges[0] == "left0A0" and edges[-1] == "C2right2"


def test_lanes_that_share_no_junction_are_on_different_levels(grid):
    assert grid.same_level("A0B0_0", "B0A0_1")  # the two directions of one road
    assert grid.same_level("A0B0_0", ":B0_3_0")  # a road and the junction it enters
    assert grid.same_level("A0B0_0", "B0B1_0")  # consecutive roads share B0
    assert not grid.same_level("A0B0_0", "A2B2_0")  # far apart: no common junction
    assert grid.same_level("", "A0B0_0")  # unknown: assume they can touch


def test_routes_respect_vclass_and_reject_u_turns(tmp_path):
    nodes = (
        '<nodes><node id="A" x="0" y="0"/><node id="B" x="200" y="0"/>'
        '<node id="C" x="400" y="0"/></nodes>'
    )
    edges = (
        "<edges>"
        '<edge id="AB" from="A" to="B" numLanes="2"><lane index="0" allow="bicycle"/></edge>'
        '<edge id="BC" from="B" to="C" numLanes="1"/><edge id="CB" from="C" to="B" numLanes="1"/>'
        '<edge id="BA" from="B" to="A" numLanes="1"/></edges>'
    )
    net = Network(build_net(tmp_path, nodes, edges))
    assert net.first_lane_allowing("AB", "passenger") == 1  # lane 0 is a bicycle lane
    assert not net.lane_allows("AB", 0, "passenger")
    net.check_edges(["AB", "BC"], vclass="passenger")
    with pytest.raises(RouteError, match="U-turn"):
        net.check_edges(["BC", "CB"])
    with pytest.raises(RouteError, match="U-turn"):
        net.shortest_route("BC", "BA")  # only reachable by turning around at C


def test_a_lane_jog_of_a_straight_connection_adds_no_curve_speed_where_sumo_moves_the_car():
    """eclipse-sumo's highway network: at junction 1658939360 the motorway's lanes jog
    4.8 m sideways within 0.3 m (netconvert's direction "s"). SUMO moves cars across at
    the lane's speed, their bodies swung across the lane beside; route following read
    it as a 1.9 m/s curve and platoons crawled through it, struck by cars passing on
    that lane at 41 m/s. Where SUMO moves the car the jog adds no curve speed; planar
    actuation, where our model drives the polyline, keeps it; real curves keep theirs."""
    import math

    from platoon_sumo.control.base import Observation
    from platoon_sumo.control.route_following import RouteFollowing, RouteFollowingParams
    from platoon_sumo.sumo.backend import resolve_sumo_path
    from platoon_sumo.vehicles import MotionLimits

    net = Network(resolve_sumo_path("sumo:tools/game/highway/highway.net.xml"))
    path = net.route_path(["191842213", "153177809", "153177820"], spacing_m=0.5)
    limits = MotionLimits(16.7, 2.5, 7.5, 1.0, max_steer_rad=0.6, wheelbase_m=2.7)
    radius = limits.wheelbase_m / math.tan(limits.max_steer_rad)
    jogs = path.jog_lanes(radius, 1.8)
    assert jogs == {":1658939360_0_0"}
    (jog,) = (c for c in path.straight_crossings if c.lane_ids == (":1658939360_0_0",))
    assert jog.sideways_m == pytest.approx(4.79, abs=0.01) and jog.advance_m < 0.5
    # a wider lane's room, or a car able to turn that tightly: no jog
    assert not jog.is_jog(radius, 1.8 - 2 * 4.8)
    assert not jog.is_jog(1.0, 1.8)

    def curve_speed(on_sumo_lanes: bool) -> np.ndarray:
        ctrl = RouteFollowing(RouteFollowingParams())
        x, y = path.xy_m[0]
        obs = Observation(
            time_s=0.0, dt_s=0.1, vehicle_id="c", role="leader", x_m=float(x), y_m=float(y),
            yaw_rad=0.55, speed_mps=10.0, front_offset_m=3.6, length_m=4.5, width_m=1.8,
            limits=limits, path=path, on_sumo_lanes=on_sumo_lanes,
        )  # fmt: skip
        ctrl.step(obs)
        return ctrl._curve_speed_mps

    at = np.isin(path.lane_index, [path.lane_ids.index(":1658939360_0_0")])
    near = np.convolve(at, np.ones(13), mode="same") > 0  # the jog and 3 m around it
    planar, sumo = curve_speed(False), curve_speed(True)
    assert planar[near].min() < 2.5
    assert sumo[near].min() == pytest.approx(path.speed_limit_mps[near].min())
    assert np.array_equal(planar[~near], sumo[~near])  # elsewhere the same profile
