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
