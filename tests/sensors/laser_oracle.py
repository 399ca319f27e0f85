"""An independent exact oracle for the laser kernel: shapely, one ray at a time.

It shares no code with platoon_sumo.sensors: rectangles are built with shapely's own
box/rotate/translate, and each ray is a LineString intersected with every outline.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import LineString, Point, box


def outlines(rectangles, segments, grow_m: float = 0.0):
    """Obstacle boundaries; ``grow_m`` inflates (> 0) or deflates (< 0) every obstacle."""
    geoms = []
    for cx, cy, yaw, length, width in np.asarray(rectangles, float).reshape(-1, 5):
        hl, hw = 0.5 * length + grow_m, 0.5 * width + grow_m
        shape = affinity.rotate(box(-hl, -hw, hl, hw), yaw, origin=(0, 0), use_radians=True)
        geoms.append(affinity.translate(shape, cx, cy).exterior)
    for x1, y1, x2, y2 in np.asarray(segments, float).reshape(-1, 4):
        if grow_m > 0.0:  # a wall inflated on all sides: a ray along its line meets the cap
            geoms.append(LineString([(x1, y1), (x2, y2)]).buffer(grow_m).exterior)
            continue
        d = np.array([x2 - x1, y2 - y1])
        n = np.hypot(*d)
        if n + 2.0 * grow_m <= 0.0:  # nothing left of it (or a point to begin with)
            geoms.append(Point(0.5 * (x1 + x2), 0.5 * (y1 + y2)))
            continue
        u = d / n  # shortened at both ends
        a, b = np.array([x1, y1]) - grow_m * u, np.array([x2, y2]) + grow_m * u
        geoms.append(LineString([a, b]))
    return geoms


def raw_first_hits(origin, heading, angles, geoms, length_m: float) -> np.ndarray:
    """Distance to the nearest boundary point on each ray (inf when none)."""
    o = np.asarray(origin, float)
    if not geoms:
        return np.full(len(angles), np.inf)
    world = heading + np.asarray(angles)
    ends = np.column_stack((o[0] + length_m * np.cos(world), o[1] + length_m * np.sin(world)))
    rays = np.array([LineString([tuple(o), tuple(e)]) for e in ends])
    hits = shapely.intersection(rays[:, None], np.array(geoms)[None, :])
    dist = shapely.distance(Point(o), hits)  # NaN where the intersection is empty
    dist = np.where(np.isnan(dist), np.inf, dist)
    return dist.min(axis=1)


def rep117(raw: np.ndarray, range_min: float, range_max: float) -> np.ndarray:
    out = raw.copy()
    out[raw > range_max] = np.inf
    out[raw < range_min] = -np.inf
    return out


def first_hits_per_obstacle(origin, heading, angles, geoms, length_m: float) -> np.ndarray:
    """Distance to each boundary alone on each ray, shape ``(len(geoms), len(angles))``
    (inf where the ray misses that boundary)."""
    o = np.asarray(origin, float)
    if not geoms:
        return np.empty((0, len(angles)))
    world = heading + np.asarray(angles)
    ends = np.column_stack((o[0] + length_m * np.cos(world), o[1] + length_m * np.sin(world)))
    rays = np.array([LineString([tuple(o), tuple(e)]) for e in ends])
    hits = shapely.intersection(np.array(geoms)[:, None], rays[None, :])
    dist = shapely.distance(Point(o), hits)  # NaN where the intersection is empty
    return np.where(np.isnan(dist), np.inf, dist)
