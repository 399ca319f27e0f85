"""Static obstacles for the laser: walls and buildings from additional files, kerbs."""

from __future__ import annotations

import numpy as np
import shapely

from platoon_sumo.sensors.laser import LaserConfig
from platoon_sumo.sensors.raycast import cast_rays
from platoon_sumo.sumo.network import Network
from platoon_sumo.sumo.shapes import read_wall_segments
from tests.helpers import PAPER_WORLD, URBAN_GRID_NET


def test_walls_of_the_paper_world_are_read_as_closed_outlines():
    segments = read_wall_segments([PAPER_WORLD / "walls.add.xml"])
    assert segments.shape[1] == 4 and len(segments) > 12
    # every wall outline closes: each end point is some segment's start point
    starts = {tuple(np.round(s[:2], 6)) for s in segments}
    assert all(tuple(np.round(s[2:], 6)) in starts for s in segments)


def test_building_polygons_count_and_other_types_do_not(tmp_path):
    add = tmp_path / "shapes.add.xml"
    add.write_text(
        "<additional>"
        '<poly id="b" type="building.yes" fill="1" shape="0,0 10,0 10,5 0,5"/>'
        '<poly id="p" type="parking" fill="1" shape="20,0 30,0 30,5"/>'
        "</additional>"
    )
    segments = read_wall_segments([add])
    assert len(segments) == 4  # the filled building is closed: 4 sides; parking ignored


def test_kerbs_bound_the_road_and_a_sideways_ray_hits_them():
    net = Network(URBAN_GRID_NET)
    kerbs = net.kerb_segments(margin_m=0.2)
    lanes = shapely.union_all(
        [
            shapely.LineString(net.lane_shape(f"{e}_{i}")).buffer(1.5)
            for e in ("A1B1",)
            for i in (0, 1)
        ]
    )
    assert not shapely.intersects(shapely.MultiLineString(kerbs.reshape(-1, 2, 2).tolist()), lanes)
    # From the middle of A1B1's right lane, a ray to the right meets the kerb 1.6 m + 0.2 m away.
    lane = net.lane_shape("A1B1_0")
    middle = lane.mean(axis=0)
    heading = float(np.arctan2(*(lane[-1] - lane[0])[::-1]))
    config = LaserConfig(-np.pi / 2, np.pi / 2, 3, 0.1, 30.0)
    ranges = cast_rays(middle, heading, config, segments=kerbs)
    assert abs(ranges[0] - 1.8) < 0.05
