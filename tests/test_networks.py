"""The committed networks: reproducible, shaped as documented, and drivable by SUMO."""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest
import sumo
import sumolib
from shapely.geometry import LineString, Point

REPO = Path(__file__).resolve().parent.parent
NETWORKS = REPO / "networks"
URBAN_GRID = NETWORKS / "urban_grid" / "urban_grid.net.xml"
URBAN_ROUTES = NETWORKS / "urban_grid" / "urban_grid.rou.xml"
PAPER_WORLD = NETWORKS / "paper_world" / "paper_world.net.xml"
PAPER_ROUTES = NETWORKS / "paper_world" / "paper_world.rou.xml"
PAPER_WALLS = NETWORKS / "paper_world" / "walls.add.xml"

# Documented in networks/paper_world/README.md.
LOOP_OUTER = ["SW_S", "S_SE", "SE_NE", "NE_N", "N_NW", "NW_SW"]
# Documented in networks/urban_grid/README.md.
CROSS_TOWN = ["left0A0", "A0B0", "B0B1", "B1B2", "B2C2", "C2right2"]

# The paper's leader laser range (m): walls beside every lane must fall inside it.
LASER_MIN_M, LASER_MAX_M = 0.30, 3.0


@pytest.fixture(scope="module")
def urban_net() -> sumolib.net.Net:
    return sumolib.net.readNet(str(URBAN_GRID), withPrograms=True)


@pytest.fixture(scope="module")
def paper_net() -> sumolib.net.Net:
    return sumolib.net.readNet(str(PAPER_WORLD), withInternal=True)


def read_routes(path: Path) -> dict[str, list[str]]:
    """Route id -> edge ids of every <route> in a route file."""
    root = ET.parse(path).getroot()
    return {route.get("id", ""): route.get("edges", "").split() for route in root.iter("route")}


def read_walls(path: Path) -> dict[str, LineString]:
    """Wall id -> polyline of every <poly type="wall"> in an additional file."""
    walls = {}
    for poly in ET.parse(path).getroot().iter("poly"):
        assert poly.get("type") == "wall"
        points = [tuple(map(float, pair.split(","))) for pair in poly.get("shape", "").split()]
        walls[poly.get("id", "")] = LineString(points)
    return walls


def normal_edges(net: sumolib.net.Net) -> list[sumolib.net.edge.Edge]:
    return [edge for edge in net.getEdges() if edge.getFunction() != "internal"]


def assert_two_lanes_each_way(net: sumolib.net.Net) -> None:
    for edge in normal_edges(net):
        assert edge.getLaneNumber() == 2, edge.getID()
        reverse = [e for e in edge.getToNode().getOutgoing() if e.getToNode() == edge.getFromNode()]
        assert len(reverse) == 1, f"{edge.getID()} has no opposite direction"
        assert reverse[0].getLaneNumber() == 2, reverse[0].getID()


def assert_route_connected(net: sumolib.net.Net, edges: list[str], *, closed: bool) -> None:
    pairs = list(itertools.pairwise(edges))
    if closed:
        pairs.append((edges[-1], edges[0]))
    for here, there in pairs:
        outgoing = net.getEdge(here).getOutgoing()
        assert net.getEdge(there) in outgoing, f"no connection {here} -> {there}"


def reachable_from(edge: sumolib.net.edge.Edge) -> set[str]:
    seen = {edge.getID()}
    todo = [edge]
    while todo:
        for nxt in todo.pop().getOutgoing():
            if nxt.getID() not in seen:
                seen.add(nxt.getID())
                todo.append(nxt)
    return seen


def test_committed_networks_match_a_rebuild() -> None:
    result = subprocess.run(
        [sys.executable, str(REPO / "tools" / "build_networks.py"), "--check"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr


# --- urban grid ------------------------------------------------------------------------


def test_urban_grid_has_nine_signalised_junctions(urban_net: sumolib.net.Net) -> None:
    tls_nodes = [node for node in urban_net.getNodes() if node.getType() == "traffic_light"]
    assert len(tls_nodes) >= 9
    for tls in urban_net.getTrafficLights():
        for program in tls.getPrograms().values():
            phases = program.getPhases()
            assert 60 <= sum(phase.duration for phase in phases) <= 90
            assert any("y" in phase.state for phase in phases)


def test_urban_grid_roads_have_two_lanes_each_way(urban_net: sumolib.net.Net) -> None:
    assert_two_lanes_each_way(urban_net)
    for edge in normal_edges(urban_net):
        for lane in edge.getLanes():
            assert lane.getWidth() == pytest.approx(3.2)
            assert lane.getSpeed() == pytest.approx(13.89)


def test_urban_grid_every_edge_reachable_from_every_entry(urban_net: sumolib.net.Net) -> None:
    edges = normal_edges(urban_net)
    entries = [edge for edge in edges if not edge.getIncoming()]
    exits = [edge for edge in edges if not edge.getOutgoing()]
    assert len(entries) == len(exits) == 12
    non_entries = {edge.getID() for edge in edges} - {edge.getID() for edge in entries}
    for entry in entries:
        assert non_entries <= reachable_from(entry), entry.getID()


def test_urban_grid_routes_are_connected(urban_net: sumolib.net.Net) -> None:
    routes = read_routes(URBAN_ROUTES)
    assert routes["cross_town"] == CROSS_TOWN
    for edges in routes.values():
        assert_route_connected(urban_net, edges, closed=False)
    signals = {urban_net.getEdge(e).getToNode().getID() for e in CROSS_TOWN[:-1]}
    assert len(signals) >= 3


# --- paper world -----------------------------------------------------------------------


def test_paper_world_roads_have_two_lanes_each_way(paper_net: sumolib.net.Net) -> None:
    assert_two_lanes_each_way(paper_net)
    for edge in normal_edges(paper_net):
        for lane in edge.getLanes():
            assert 0.5 <= lane.getWidth() <= 0.6
            assert lane.getSpeed() == pytest.approx(0.5)


def test_paper_world_loops_are_closed(paper_net: sumolib.net.Net) -> None:
    routes = read_routes(PAPER_ROUTES)
    assert routes["loop_outer"] == LOOP_OUTER
    for edges in routes.values():
        assert_route_connected(paper_net, edges, closed=True)
    # The paper's platoon keeps to the right lane: the outer loop needs no lane change.
    for here, there in itertools.pairwise([*LOOP_OUTER, LOOP_OUTER[0]]):
        right_lane = paper_net.getEdge(here).getLane(0)
        assert any(c.getToLane().getID() == f"{there}_0" for c in right_lane.getOutgoing())


def test_paper_world_walls_do_not_touch_lanes(paper_net: sumolib.net.Net) -> None:
    walls = read_walls(PAPER_WALLS)
    assert set(walls) == {"wall_outer", "wall_block_0", "wall_block_1"}
    for edge in paper_net.getEdges(withInternal=True):
        for lane in edge.getLanes():
            footprint = LineString(lane.getShape()).buffer(lane.getWidth() / 2, cap_style="flat")
            for wall_id, wall in walls.items():
                assert not wall.intersects(footprint), f"{wall_id} crosses {lane.getID()}"


def test_paper_world_walls_are_seen_beside_every_lane(paper_net: sumolib.net.Net) -> None:
    """A robot in the middle of any lane sees a wall to its left and to its right."""
    walls = list(read_walls(PAPER_WALLS).values())
    for edge in normal_edges(paper_net):
        for lane in edge.getLanes():
            (x0, y0), (x1, y1) = lane.getShape()[0], lane.getShape()[-1]
            heading = math.atan2(y1 - y0, x1 - x0)
            centre = Point((x0 + x1) / 2, (y0 + y1) / 2)
            for side in (math.pi / 2, -math.pi / 2):
                ray = LineString(
                    [
                        centre,
                        (
                            centre.x + LASER_MAX_M * math.cos(heading + side),
                            centre.y + LASER_MAX_M * math.sin(heading + side),
                        ),
                    ]
                )
                hits = [centre.distance(ray.intersection(wall)) for wall in walls]
                hits = [d for d in hits if d > 0 and not math.isnan(d)]
                assert hits, f"no wall within {LASER_MAX_M} m beside {lane.getID()}"
                assert min(hits) >= LASER_MIN_M, lane.getID()


@pytest.fixture
def paper_world_sim() -> Iterator[ModuleType]:
    """A libsumo run of the paper world with its routes and walls; always closed."""
    import libsumo

    binary = os.path.join(sumo.SUMO_HOME, "bin", "sumo")
    libsumo.start(
        [
            binary,
            "-n", str(PAPER_WORLD),
            "-r", str(PAPER_ROUTES),
            "-a", str(PAPER_WALLS),
            "--no-step-log",
            "--step-length", "0.1",
            "--collision.action", "warn",
        ]
    )  # fmt: skip
    try:
        yield libsumo
    finally:
        libsumo.close()


def test_robot_drives_the_outer_loop_in_the_right_lane(paper_world_sim: ModuleType) -> None:
    sim = paper_world_sim
    assert sorted(sim.polygon.getIDList()) == ["wall_block_0", "wall_block_1", "wall_outer"]
    assert sim.vehicletype.getLength("robot") == pytest.approx(0.3)
    assert sim.vehicletype.getWidth("robot") == pytest.approx(0.25)
    sim.vehicle.add("robot0", "loop_outer", typeID="robot", departLane="0")
    visited: list[str] = []
    for _ in range(700):  # 70 s: along SW_S, through S, along S_SE, round the SE corner
        sim.simulationStep()
        road = sim.vehicle.getRoadID("robot0")
        if not road.startswith(":"):
            assert road in LOOP_OUTER
            assert sim.vehicle.getLaneIndex("robot0") == 0
            if not visited or visited[-1] != road:
                visited.append(road)
    assert visited == LOOP_OUTER[:3]
    assert sim.vehicle.getSpeed("robot0") == pytest.approx(0.2)


@pytest.fixture
def urban_grid_sim() -> Iterator[ModuleType]:
    """A libsumo run of the urban grid with its named routes; always closed."""
    import libsumo

    binary = os.path.join(sumo.SUMO_HOME, "bin", "sumo")
    libsumo.start([binary, "-n", str(URBAN_GRID), "-r", str(URBAN_ROUTES), "--no-step-log"])
    try:
        yield libsumo
    finally:
        libsumo.close()


def test_car_drives_cross_town_through_the_signals(urban_grid_sim: ModuleType) -> None:
    sim = urban_grid_sim
    sim.vehicle.add("car0", "cross_town", departLane="best")
    for _ in range(400):  # 1 s steps; 1.1 km at 50 km/h plus red lights
        sim.simulationStep()
        if sim.simulation.getMinExpectedNumber() == 0:
            break
    assert list(sim.simulation.getArrivedIDList()) == ["car0"]
