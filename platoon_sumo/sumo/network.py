"""Offline knowledge of a SUMO network (read with sumolib, no simulation needed).

Used to validate scenarios before a run (edges exist, routes connect), to route
from/to edges, and to build each route's centre-line path including the internal
junction lanes, with the lanes chosen so that the route needs the fewest lane changes.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import sumolib
from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.ops import unary_union

from platoon_sumo.errors import did_you_mean
from platoon_sumo.path import LaneChange, RoutePath, StraightCrossing


class RouteError(ValueError):
    """A route that cannot be driven; `index` is the offending position in the edge list."""

    def __init__(self, message: str, index: int | None = None, hint: str | None = None):
        super().__init__(message)
        self.index = index
        self.hint = hint


@dataclass(frozen=True)
class _Link:
    """One connection between consecutive route edges, with its junction lanes."""

    from_lane: int
    to_lane: int
    via_lane_ids: tuple[str, ...]
    turnaround: bool = False
    straight: bool = False
    """netconvert's direction "s": straight through the junction."""


#: Parts of the ids netconvert gives edges it invents when guessing ramps.
INVENTED_EDGE_MARKS = ("-AddedOnRampEdge", "-AddedOffRampEdge")
#: Prefix of the ids of junctions netconvert joined into one.
JOINED_NODE_PREFIX = "cluster_"
#: A route crossing a joined junction on longer internal lanes than this is reported [m].
LONG_JOINED_CROSSING_M = 30.0


class Network:
    """A read-only view of a `.net.xml` file."""

    def __init__(self, net_file: str | Path):
        self.path = Path(net_file)
        self._net: Any = sumolib.net.readNet(str(self.path), withInternal=True)
        self._normal_edges = {
            e.getID(): e for e in self._net.getEdges(withInternal=False) if e.getFunction() == ""
        }
        self._lane_nodes: dict[str, frozenset[str]] = {}

    def edge_suggestion(self, edge_id: str) -> str | None:
        return did_you_mean(edge_id, self._normal_edges)

    def edge_length_m(self, edge_id: str) -> float:
        return float(self._normal_edges[edge_id].getLength())

    def max_lane_speed_mps(self, edges: Sequence[str]) -> float:
        """The highest speed limit of any lane of these edges [m/s]."""
        return max(
            float(lane.getSpeed()) for e in edges for lane in self._normal_edges[e].getLanes()
        )

    def lane_count(self, edge_id: str) -> int:
        return len(self._normal_edges[edge_id].getLanes())

    def lane_shape(self, lane_id: str) -> np.ndarray:
        """(k, 2) centre-line of a lane, internal junction lanes included."""
        return np.asarray(self._net.getLane(lane_id).getShape(), dtype=np.float64)

    def lane_frame(self, lane_id: str, x_m: float, y_m: float) -> tuple[float, float, float] | None:
        """(direction [rad], position [m], offset [m]) at the point of the lane's centre
        line nearest to (x, y): the direction of its segment, its distance along the
        lane from the start (0 to the lane's length), and how far (x, y) is from that
        segment's line, to its left (+) or right (-); None for an unknown lane."""
        try:
            shape = self.lane_shape(lane_id)
        except (KeyError, ValueError):  # sumolib's answers to an unknown lane id
            return None
        if len(shape) < 2:
            return None
        a, d = shape[:-1], np.diff(shape, axis=0)
        length2 = np.maximum((d * d).sum(axis=1), 1e-12)
        t = np.clip(((np.array([x_m, y_m]) - a) * d).sum(axis=1) / length2, 0.0, 1.0)
        nearest = a + t[:, None] * d
        k = int(np.argmin(np.hypot(*(nearest - (x_m, y_m)).T)))
        seg = np.sqrt(length2)
        position = float(seg[:k].sum() + t[k] * seg[k])
        offset = float(d[k, 0] * (y_m - a[k, 1]) - d[k, 1] * (x_m - a[k, 0])) / seg[k]
        return float(np.arctan2(d[k, 1], d[k, 0])), position, offset

    @functools.lru_cache(maxsize=65536)  # noqa: B019 - one Network per run, bounded cache
    def junction_successor(self, lane_id: str) -> str | None:
        """The lane a junction lane leads to (its one connection); None for others."""
        if not lane_id.startswith(":"):
            return None
        outgoing = self._net.getLane(lane_id).getOutgoing()
        if len(outgoing) != 1:
            return None
        return str(outgoing[0].getViaLaneID() or outgoing[0].getToLane().getID())

    def road_area(self) -> BaseGeometry:
        """Union of every lane's footprint and every junction's shape: where vehicles drive."""
        parts = [Polygon(n.getShape()) for n in self._net.getNodes() if len(n.getShape()) >= 3]
        for edge in self._net.getEdges(withInternal=True):
            for lane in edge.getLanes():
                centre = LineString(lane.getShape())
                parts.append(centre.buffer(lane.getWidth() / 2.0, cap_style="flat"))
        return unary_union(parts)

    def kerb_segments(self, margin_m: float = 0.0) -> np.ndarray:
        """(M, 4) segments of the road area's boundary grown by `margin_m`: kerbs a laser sees."""
        area = self.road_area()
        if margin_m > 0:
            area = area.buffer(margin_m, join_style="mitre")
        polygons = list(getattr(area, "geoms", [area]))
        rings = [ring for poly in polygons for ring in (poly.exterior, *poly.interiors)]
        segments = []
        for ring in rings:
            pts = np.asarray(ring.coords, dtype=np.float64)
            segments.append(np.hstack([pts[:-1], pts[1:]]))
        return np.vstack(segments) if segments else np.empty((0, 4))

    @functools.lru_cache(maxsize=65536)  # noqa: B019 - one Network per run, bounded cache
    def lane_nodes(self, lane_id: str) -> frozenset[str]:
        """Junctions a lane touches: its edge's two ends, or the junction it lies in
        (kept per lane: the loop asks for the lanes around the platoons every step)."""
        known = self._lane_nodes.get(lane_id)
        if known is not None:
            return known
        if lane_id.startswith(":"):
            nodes = frozenset({lane_id[1:].rsplit("_", 2)[0]})
        else:
            edge = self._normal_edges.get(lane_id.rsplit("_", 1)[0])
            nodes = (
                frozenset()
                if edge is None
                else frozenset({edge.getFromNode().getID(), edge.getToNode().getID()})
            )
        self._lane_nodes[lane_id] = nodes
        return nodes

    def same_level(self, lane_a: str, lane_b: str) -> bool:
        """Can vehicles on these lanes touch? Lanes that cross without sharing a junction
        (a bridge over a road; nets carry no heights) cannot. Unknown lanes: assume yes."""
        a, b = self.lane_nodes(lane_a), self.lane_nodes(lane_b)
        return not a or not b or bool(a & b)

    def tls_ids(self) -> list[str]:
        return sorted(t.getID() for t in self._net.getTrafficLights())

    def invented_on_route(self, edges: Sequence[str]) -> list[str]:
        """What netconvert made up on this route, one message each: ramps it guessed
        (`--ramps.guess`: their lanes and merges are invented) and junctions it joined
        (`--junctions.join`) that the route crosses on internal lanes longer than
        `LONG_JOINED_CROSSING_M` (a car may have to wait inside such a crossing)."""
        found = []
        for a, b in itertools.pairwise(edges):
            if any(mark in b for mark in INVENTED_EDGE_MARKS):
                found.append(f"edge '{b}' is a ramp netconvert guessed (--ramps.guess)")
            node = self._normal_edges[a].getToNode().getID()
            if node.startswith(JOINED_NODE_PREFIX):
                crossing = self._crossing_length_m(a, b)
                if crossing > LONG_JOINED_CROSSING_M:
                    name = node if len(node) <= 48 else node[:44] + "..."  # clusters of many
                    found.append(
                        f"junction '{name}' between '{a}' and '{b}' was joined by netconvert "
                        f"(--junctions.join); the route crosses it on {crossing:.0f} m of "
                        "internal lanes"
                    )
        return found

    def _crossing_length_m(self, a: str, b: str) -> float:
        """Length of the internal lanes from edge `a` into edge `b` (the longest link)."""
        longest = 0.0
        for conn in self._normal_edges[a].getOutgoing().get(self._normal_edges[b], []):
            length, via = 0.0, conn.getViaLaneID()
            while via:
                lane = self._net.getLane(via)
                length += lane.getLength()
                nxt = [c.getViaLaneID() for c in lane.getOutgoing() if c.getViaLaneID()]
                via = nxt[0] if nxt else ""
            longest = max(longest, length)
        return longest

    def check_edges(self, edges: Sequence[str], vclass: str = "passenger") -> None:
        """Raise RouteError if an edge is unknown, two consecutive edges do not connect for
        `vclass`, or the route turns around (a U-turn no vehicle model here can drive)."""
        if not edges:
            raise RouteError("a route needs at least one edge")
        self.check_edges_exist(edges)
        for i, (a, b) in enumerate(itertools.pairwise(edges)):
            links = self._links(a, b, vclass)
            if not links:
                successors = sorted(e.getID() for e in self._normal_edges[a].getOutgoing())
                raise RouteError(
                    f"edge '{a}' does not connect to '{b}' for vClass {vclass} (successors "
                    f"of '{a}': {', '.join(successors) or 'none'})",
                    index=i + 1,
                )
            if all(link.turnaround for link in links):
                raise RouteError(
                    f"the route turns around from '{a}' into '{b}' (a U-turn)",
                    index=i + 1,
                    hint="choose other from/to edges or add via_edges that avoid it",
                )

    def shortest_route(
        self, from_edge: str, to_edge: str, via_edges: Sequence[str] = (), vclass: str = "passenger"
    ) -> list[str]:
        """Fastest route through the waypoints (travel time at the speed limit)."""
        waypoints = [from_edge, *via_edges, to_edge]
        self.check_edges_exist(waypoints)
        route: list[str] = [from_edge]
        for a, b in itertools.pairwise(waypoints):
            found = self._net.getFastestPath(
                self._normal_edges[a], self._normal_edges[b], vClass=vclass
            )[0]
            if not found:
                raise RouteError(f"no route from edge '{a}' to edge '{b}' for vClass {vclass}")
            route.extend(e.getID() for e in found[1:])
        try:
            self.check_edges(route, vclass)
        except RouteError as exc:
            raise RouteError(f"the fastest route {exc}", None, exc.hint) from None
        return route

    def first_lane_allowing(self, edge_id: str, vclass: str) -> int | None:
        """Index of the rightmost lane of the edge that `vclass` may use (None: none)."""
        for lane in self._normal_edges[edge_id].getLanes():
            if lane.allows(vclass):
                return int(lane.getIndex())
        return None

    def lane_allows(self, edge_id: str, index: int, vclass: str) -> bool:
        return bool(self._normal_edges[edge_id].getLane(index).allows(vclass))

    def check_edges_exist(self, edges: Sequence[str]) -> None:
        for i, edge_id in enumerate(edges):
            if edge_id not in self._normal_edges:
                raise RouteError(
                    f"unknown edge '{edge_id}'", index=i, hint=self.edge_suggestion(edge_id)
                )

    @functools.lru_cache(maxsize=4096)  # noqa: B019 - one Network per run, bounded cache
    def _links(self, from_edge: str, to_edge: str, vclass: str = "passenger") -> tuple[_Link, ...]:
        edge = self._normal_edges[from_edge]
        target = self._normal_edges.get(to_edge)
        links = []
        for conn in edge.getOutgoing().get(target, []):
            if not (conn.getFromLane().allows(vclass) and conn.getToLane().allows(vclass)):
                continue
            vias: list[str] = []
            via_id = conn.getViaLaneID()
            while via_id:
                vias.append(via_id)
                nxt = [c.getViaLaneID() for c in self._net.getLane(via_id).getOutgoing()]
                via_id = nxt[0] if nxt else ""
            links.append(
                _Link(
                    conn.getFromLane().getIndex(),
                    conn.getToLane().getIndex(),
                    tuple(vias),
                    conn.getDirection() == "t",
                    conn.getDirection() == "s",
                )
            )
        return tuple(links)

    def route_path(
        self,
        edges: Sequence[str],
        spacing_m: float,
        first_lane: int | None = None,
        vclass: str = "passenger",
    ) -> RoutePath:
        """Centre-line of `edges` from the start of the first to the end of the last edge.

        Lanes are chosen by dynamic programming over the connections at each junction:
        fewest lane changes first, then the rightmost lanes. A lane change within an edge
        is a smooth lateral blend over the middle of that edge.
        """
        self.check_edges(edges, vclass)
        links = self._choose_links(edges, first_lane, vclass)
        pieces: list[np.ndarray] = []
        lane_ids: list[str] = []
        speeds: list[float] = []
        widths: list[float] = []
        entry_lane = first_lane if first_lane is not None else None
        changes: list[LaneChange] = []
        crossings: list[StraightCrossing] = []
        offset_m = 0.0
        for i, edge_id in enumerate(edges):
            edge = self._normal_edges[edge_id]
            exit_lane = links[i].from_lane if i < len(links) else None
            start = entry_lane if entry_lane is not None else exit_lane
            start = start if start is not None else 0
            end = exit_lane if exit_lane is not None else start
            lane_a, lane_b = edge.getLane(start), edge.getLane(end)
            piece = _blend(np.asarray(lane_a.getShape()), np.asarray(lane_b.getShape()))
            length = _length(piece)
            if start != end:
                step = 1 if end > start else -1
                targets = tuple(
                    edge.getLane(k).getID() for k in range(start + step, end + step, step)
                )
                changes.append(
                    LaneChange(
                        offset_m + BLEND[0] * length,
                        offset_m + BLEND[1] * length,
                        targets,
                        BLEND[0] * lane_b.getLength(),
                    )
                )
            offset_m += length
            pieces.append(piece)
            lane_ids.append(lane_a.getID())
            speeds.append(min(lane_a.getSpeed(), lane_b.getSpeed()))
            widths.append(min(lane_a.getWidth(), lane_b.getWidth()))
            if i < len(links):
                if links[i].straight and links[i].via_lane_ids:
                    crossings.append(self._straight_crossing(lane_b, links[i].via_lane_ids))
                for via_id in links[i].via_lane_ids:
                    via = self._net.getLane(via_id)
                    pieces.append(np.asarray(via.getShape()))
                    offset_m += _length(pieces[-1])
                    lane_ids.append(via_id)
                    speeds.append(via.getSpeed())
                    widths.append(via.getWidth())
                entry_lane = links[i].to_lane
        return RoutePath.from_pieces(
            pieces, lane_ids, speeds, widths, spacing_m, changes, tuple(crossings)
        )

    def _straight_crossing(self, lane: Any, via_lane_ids: tuple[str, ...]) -> StraightCrossing:
        """A straight-through connection's junction lanes from `lane` (sumolib's), with
        how far their chord advances along the direction `lane` ends in and how far it
        moves sideways."""
        shape = np.asarray(lane.getShape(), dtype=np.float64)
        ux, uy = shape[-1] - shape[-2]
        norm = math.hypot(ux, uy) or 1.0
        ux, uy = ux / norm, uy / norm
        first = self._net.getLane(via_lane_ids[0])
        last = self._net.getLane(via_lane_ids[-1])
        (ax, ay), (bx, by) = first.getShape()[0], last.getShape()[-1]
        dx, dy = bx - ax, by - ay
        return StraightCrossing(
            via_lane_ids, dx * ux + dy * uy, abs(ux * dy - uy * dx), float(first.getWidth())
        )

    def _choose_links(
        self, edges: Sequence[str], first_lane: int | None, vclass: str
    ) -> list[_Link]:
        """One connection per junction: fewest lane changes, then rightmost lanes."""
        options = [self._links(a, b, vclass) for a, b in itertools.pairwise(edges)]
        if not options:
            return []
        change_cost = 100  # one lane change outweighs any preference for the right lane

        def start_cost(link: _Link) -> int:
            shift = abs(link.from_lane - first_lane) if first_lane is not None else 0
            return shift * change_cost + link.from_lane

        cost = [start_cost(link) for link in options[0]]
        back: list[list[int]] = []
        for prev, here in itertools.pairwise(options):
            new_cost, choice = [], []
            for link in here:
                steps = [cost[k] + abs(p.to_lane - link.from_lane) * change_cost
                         for k, p in enumerate(prev)]  # fmt: skip
                best = int(np.argmin(steps))
                choice.append(best)
                new_cost.append(steps[best] + link.from_lane)
            cost = new_cost
            back.append(choice)
        k = int(np.argmin(cost))
        chosen = [k]
        for choice in reversed(back):
            k = choice[k]
            chosen.append(k)
        chosen.reverse()
        return [opts[k] for opts, k in zip(options, chosen, strict=True)]


#: Share of an edge's length where a lane change begins and ends.
BLEND = (0.25, 0.75)


def _length(polyline: np.ndarray) -> float:
    return float(np.hypot(*np.diff(polyline, axis=0).T).sum())


def _blend(shape_a: np.ndarray, shape_b: np.ndarray) -> np.ndarray:
    """Polyline leaving along shape_a and arriving along shape_b (same edge, other lane)."""
    if shape_a.shape == shape_b.shape and np.allclose(shape_a, shape_b):
        return shape_a
    n = 50
    t = np.linspace(0.0, 1.0, n)
    a = _resample(shape_a, t)
    b = _resample(shape_b, t)
    # Smoothstep over the middle of the edge: the change happens mid-block.
    u = np.clip((t - BLEND[0]) / (BLEND[1] - BLEND[0]), 0.0, 1.0)
    w = u * u * (3 - 2 * u)
    return a * (1 - w)[:, None] + b * w[:, None]


def _resample(shape: np.ndarray, t: np.ndarray) -> np.ndarray:
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T))])
    target = t * s[-1]
    return np.column_stack([np.interp(target, s, shape[:, 0]), np.interp(target, s, shape[:, 1])])
