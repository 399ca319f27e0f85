"""The neighbour kernels against brute force, and the world read around the platoon
vehicles (`SumoBackend.snapshot`) against every vehicle SUMO has."""

from __future__ import annotations

import math
import random
from pathlib import Path

import libsumo
import numpy as np
import pytest
import sumolib
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.kernels.neighbours import lanes_within, within_radius
from platoon_sumo.sumo.backend import (
    _LANE_SHAPE_TOLERANCE_M,
    SumoBackend,
    SumoOptions,
    _LaneGrid,
)
from tests.helpers import REPO, URBAN_GRID_NET

DRT_CITY_NET = REPO / "networks" / "drt_city" / "drt_city.net.xml.gz"

coordinates = st.floats(-200.0, 200.0, allow_nan=False)
points = st.lists(st.tuples(coordinates, coordinates), min_size=1, max_size=12)


def segment_distances(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """(points, segments) distances by projection clamped to each segment."""
    a, b = segments[None, :, :2], segments[None, :, 2:]
    p = points[:, None, :]
    ab = b - a
    squared = (ab * ab).sum(-1)
    t = np.where(squared > 0, ((p - a) * ab).sum(-1) / np.where(squared > 0, squared, 1), 0)
    closest = a + np.clip(t, 0, 1)[..., None] * ab
    return np.hypot(*np.moveaxis(closest - p, -1, 0))


class _Lanes:
    """A stand-in for libsumo's lane domain (its method names): shapes, widths and
    allowed vehicle classes of made-up lanes (by default every lane allows cars)."""

    def __init__(
        self,
        shapes: list[list[tuple[float, float]]],
        widths: list[float],
        allowed: list[tuple[str, ...]] | None = None,
    ):
        self.shapes = {f"l{k:02d}": s for k, s in enumerate(shapes)}
        self.widths = dict(zip(self.shapes, widths, strict=True))
        classes = allowed if allowed is not None else [("passenger",)] * len(shapes)
        self.allowed = dict(zip(self.shapes, classes, strict=True))

    def getIDList(self):
        return list(self.shapes)

    def getShape(self, lane):
        return self.shapes[lane]

    def getWidth(self, lane):
        return self.widths[lane]

    def getAllowed(self, lane):
        return self.allowed[lane]


class _Api:
    def __init__(self, lanes: _Lanes):
        self.lane = lanes


@settings(max_examples=200, deadline=None)
@given(
    centres=points,
    candidates=st.lists(st.tuples(coordinates, coordinates), max_size=30),
    radius=st.floats(0.0, 120.0),
)
def test_within_radius_is_any_centre_within_the_radius(centres, candidates, radius):
    c = np.array(centres, dtype=np.float64).reshape(-1, 2)
    p = np.array(candidates, dtype=np.float64).reshape(-1, 2)
    nearest = np.hypot(*np.moveaxis(p[:, None] - c[None], -1, 0)).min(axis=1, initial=np.inf)
    clear = np.abs(nearest - radius) > 1e-9  # off the rounding's knife edge
    got = within_radius(c, p, radius)
    np.testing.assert_array_equal(got[clear], (nearest <= radius)[clear])


@settings(max_examples=200, deadline=None)
@given(
    shapes=st.lists(
        st.lists(st.tuples(coordinates, coordinates), min_size=1, max_size=5),
        min_size=1,
        max_size=12,
    ),
    widths=st.lists(st.floats(2.0, 6.0), min_size=12, max_size=12),
    centres=points,
    radius=st.floats(0.0, 120.0),
    cell_m=st.sampled_from([5.0, 50.0, 400.0]),
)
def test_lane_grid_lists_exactly_the_lanes_within_reach(shapes, widths, centres, radius, cell_m):
    """A lane is listed where one of its segments lies within the radius plus its pad
    (half its width and the tolerance) of a point: brute force over every segment."""
    lanes = _Lanes(shapes, widths[: len(shapes)])
    grid = _LaneGrid.build(_Api(lanes), cell_m)  # type: ignore[arg-type]
    p = np.array(centres, dtype=np.float64)
    listed = grid.near(p, radius, grid.listable(frozenset({"passenger"})))
    assert listed == sorted(listed)
    for lane, shape in lanes.shapes.items():
        s = np.array(shape if len(shape) > 1 else shape * 2, dtype=np.float64)
        segments = np.hstack([s[:-1], s[1:]])
        beyond = segment_distances(p, segments).min() - radius - 0.5 * lanes.widths[lane]
        beyond -= _LANE_SHAPE_TOLERANCE_M
        if abs(beyond) > 1e-9:  # off the rounding's knife edge
            assert (lane in listed) == (beyond < 0), lane


def test_lanes_within_marks_nothing_without_points():
    grid = _LaneGrid.build(_Api(_Lanes([[(0.0, 0.0), (10.0, 0.0)]], [3.2])), 50.0)  # type: ignore[arg-type]
    assert grid.near(np.zeros((0, 2)), 50.0, np.ones(1, dtype=bool)) == []
    assert not lanes_within(
        np.zeros((0, 2)), 1.0, grid.origin, grid.cell_m, grid.cells_y, grid.cell_starts,
        grid.cell_segments, grid.segments, grid.pads, grid.segment_lane, 1,
    ).any()  # fmt: skip


def test_lanes_no_vehicle_class_in_the_network_may_use_are_not_listed():
    """Sidewalks and crossings (pedestrian only) are left out while no vehicle of a
    class they allow drives; a lane that lists no class allows every class."""
    shape = [[(0.0, 0.0), (10.0, 0.0)]] * 4
    allowed = [("passenger", "bus"), ("pedestrian",), ("bicycle", "pedestrian"), ()]
    grid = _LaneGrid.build(_Api(_Lanes(shape, [3.0] * 4, allowed)), 50.0)  # type: ignore[arg-type]
    near = np.array([[5.0, 1.0]])
    cars = grid.listable(frozenset({"passenger", "truck"}))
    assert grid.near(near, 5.0, cars) == ["l00", "l03"]
    with_bikes = grid.listable(frozenset({"passenger", "bicycle"}))
    assert grid.near(near, 5.0, with_bikes) == ["l00", "l02", "l03"]
    # SUMO's class `ignoring` drives wherever it likes
    anywhere = grid.listable(frozenset({"passenger", "ignoring"}))
    assert grid.near(near, 5.0, anywhere) == ["l00", "l01", "l02", "l03"]


FLOWS = "<routes>{}</routes>".format(
    "".join(
        f'<flow id="{r}" route="{r}" begin="0" end="200" period="1.5" departLane="random" '
        'departPosLat="random"/>'
        for r in ("cross_town", "west_east", "east_west", "south_north", "north_south")
    )
)


def _urban_routes(folder: Path) -> tuple[str, tuple[str, ...]]:
    """The urban grid with flows along its named routes (sublane model: cars off
    their lanes' centres)."""
    flows = folder / "flows.rou.xml"
    flows.write_text(FLOWS, encoding="utf-8")
    return str(URBAN_GRID_NET), (str(URBAN_GRID_NET.with_name("urban_grid.rou.xml")), str(flows))


def _city_routes(folder: Path) -> tuple[str, tuple[str, ...]]:
    """The DRT city (sidewalks, crossings and walking areas: a third of its lanes are
    for pedestrians only) with cars and buses between random pairs of its roads."""
    net = sumolib.net.readNet(str(DRT_CITY_NET))
    roads = sorted(e.getID() for e in net.getEdges() if e.allows("passenger"))
    rng = random.Random(7)
    flows = "".join(
        f'<flow id="f{k}" type="{("car", "city_bus")[k % 2]}" from="{rng.choice(roads)}" '
        f'to="{rng.choice(roads)}" begin="0" end="200" period="2"/>'
        for k in range(24)
    )
    types = '<vType id="car"/><vType id="city_bus" vClass="bus" length="12"/>'
    routes = folder / "city.rou.xml"
    routes.write_text(f"<routes>{types}{flows}</routes>", encoding="utf-8")
    return str(DRT_CITY_NET), (str(routes),)


@pytest.fixture(scope="module", params=["urban_grid", "drt_city"])
def traffic(request, tmp_path_factory):
    """A network with traffic 120 s in: a few hundred cars."""
    make = _urban_routes if request.param == "urban_grid" else _city_routes
    net, routes = make(tmp_path_factory.mktemp(request.param))
    options = SumoOptions(net, 0.1, 1, route_files=routes, extra_args=("--ignore-route-errors",))
    backend = SumoBackend(options)
    backend.start()
    try:
        for _ in range(1200):
            backend.step()
        yield request.param, backend
    finally:
        backend.close()


@pytest.mark.parametrize("radius_m", [5.0, 43.1, 150.0])
def test_snapshot_holds_every_vehicle_within_the_radius_of_the_given_ones(traffic, radius_m):
    """The lanes near the given cars are listed, and only those a vehicle in the
    network may use: the snapshot still holds every vehicle whose front bumper is
    within the radius of one of theirs, with its own lane, position, heading and speed,
    as SUMO reads each of them. Lanes within reach that allow no vehicle class in the
    network are not listed: in the city, footways among them."""
    name, backend = traffic
    everyone = list(libsumo.vehicle.getIDList())
    assert len(everyone) > 100
    wanted = everyone[::15]
    world = backend.snapshot(wanted, radius_m)
    xy = np.array([libsumo.vehicle.getPosition(v) for v in everyone])
    centres = xy[[everyone.index(v) for v in wanted]]
    distance = np.hypot(*np.moveaxis(xy[:, None] - centres[None], -1, 0)).min(axis=1)
    expected = {v for v, d in zip(everyone, distance, strict=True) if d <= radius_m}
    assert set(world.ids) == expected | set(wanted)
    assert world.ids[: len(wanted)] == tuple(wanted)
    for k, vid in enumerate(world.ids):
        assert world.lane_ids[k] == libsumo.vehicle.getLaneID(vid)
        assert (world.front_x_m[k], world.front_y_m[k]) == libsumo.vehicle.getPosition(vid)
        assert world.speed_mps[k] == libsumo.vehicle.getSpeed(vid)
        heading = math.radians(90.0 - libsumo.vehicle.getAngle(vid))
        assert world.yaw_rad[k] == pytest.approx(heading, abs=1e-12)
        assert world.index[vid] == k
    grid, (_, listable) = backend._lane_grid, backend._listable
    centres_now = np.array([libsumo.vehicle.getPosition(v) for v in wanted])
    within = grid.near(centres_now, radius_m, np.ones(len(grid.lane_ids), dtype=bool))
    listed = grid.near(centres_now, radius_m, listable)
    skipped = set(within) - set(listed)
    classes = {libsumo.vehicle.getVehicleClass(v) for v in everyone}
    assert all(classes.isdisjoint(libsumo.lane.getAllowed(lane)) for lane in skipped)
    footways = {lane for lane in skipped if libsumo.lane.getAllowed(lane) == ("pedestrian",)}
    assert bool(footways) == (name == "drt_city")
