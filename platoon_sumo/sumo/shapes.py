"""Static obstacles from SUMO additional files: `<poly>` outlines as wall segments."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

#: Polygon types that a laser sees (walls of the paper's world, buildings from OSM).
SOLID_TYPES = ("wall", "building")


def read_wall_segments(
    files: Iterable[Path], types: Iterable[str] = SOLID_TYPES
) -> NDArray[np.float64]:
    """(M, 4) segments `(x1, y1, x2, y2)` of every solid polygon outline in `files`.

    A polygon whose type starts with one of `types` (OSM buildings are `building.yes`, ...)
    counts; filled polygons are closed, outlines are taken as drawn.
    """
    wanted = tuple(types)
    segments: list[NDArray[np.float64]] = []
    for path in files:
        for poly in ET.parse(path).getroot().iter("poly"):
            if not poly.get("type", "").startswith(wanted):
                continue
            pts = np.array(
                [[float(c) for c in p.split(",")[:2]] for p in poly.get("shape", "").split()]
            )
            if len(pts) < 2:
                continue
            filled = poly.get("fill", "0") in ("1", "true")
            if filled and not np.allclose(pts[0], pts[-1]):
                pts = np.vstack([pts, pts[:1]])
            segments.append(np.hstack([pts[:-1], pts[1:]]))
    if not segments:
        return np.empty((0, 4))
    return np.vstack(segments)
