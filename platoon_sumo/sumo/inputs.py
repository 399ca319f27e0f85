"""Cheap checks of the SUMO XML files a scenario names, before SUMO starts.

SUMO's own messages about a route file name neither the scenario key nor, often, the
file; a corrupt file ends in a parse error deep in a run. These checks stream each file
once (`iterparse`, elements cleared as they end) and report the first problem as one
line naming the file, the line and the vehicle (or polygon). They check only what is
cheap and certain: well-formed XML; the edges of `<route edges=...>` and the
`from`/`to`/`via` edges of trips and flows exist in the network; `begin`, `end` and
`depart` are times (a number, or SUMO's `[[D:]H:]M:S` form; `depart` also one of
SUMO's words) and finite; a `<poly>` shape is a list of finite `x,y` points.
"""

from __future__ import annotations

import gzip
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from platoon_sumo.sumo.network import Network, RouteError

#: Elements of a route file that are one vehicle or a stream of them.
_DEMAND = ("vehicle", "trip", "flow", "person", "container")
#: `depart` values that are not times.
_DEPART_WORDS = ("triggered", "containerTriggered", "now", "begin", "split")
_CLOCK = re.compile(r"\d+(:\d+){1,3}(\.\d*)?")


class InputFileError(ValueError):
    """A problem in one input file: the message names the file and where in it."""


def _open(path: Path) -> IO[bytes]:
    if path.suffix == ".gz":
        return gzip.open(path, "rb")  # type: ignore[return-value]
    return path.open("rb")


def _elements(path: Path) -> Iterator[tuple[str, ET.Element]]:
    """(event, element) for start and end events; each child of the root is dropped once
    the caller has seen its end (memory stays small for big files). Parse errors are
    InputFileError naming the line."""
    try:
        with _open(path) as stream:
            parser: Any = ET.XMLPullParser(("start", "end"))
            root: ET.Element | None = None
            depth = 0
            while True:
                chunk = stream.read(1 << 16)
                if chunk:
                    parser.feed(chunk)
                else:
                    parser.close()
                for event, element in parser.read_events():
                    assert isinstance(element, ET.Element)
                    if event == "start":
                        depth += 1
                        root = element if root is None else root
                    yield event, element
                    if event == "end":
                        depth -= 1
                        if depth == 1 and root is not None:
                            root.clear()
                if not chunk:
                    return
    except ET.ParseError as exc:
        raise InputFileError(f"{path} cannot be read as XML: not well-formed ({exc})") from None
    except (OSError, EOFError) as exc:
        raise InputFileError(f"{path} cannot be read as XML ({exc})") from None


def check_xml(path: Path) -> None:
    """The file is well-formed XML and its `<poly>` shapes are lists of finite points."""
    for event, element in _elements(path):
        if event == "end" and element.tag == "poly" and not _shape_ok(element.get("shape", "")):
            raise InputFileError(
                f"{path}: poly '{element.get('id', '?')}': shape must be a list "
                "of finite x,y points"
            )


def _shape_ok(shape: str) -> bool:
    try:
        points = [[float(c) for c in p.split(",")[:2]] for p in shape.split()]
    except ValueError:
        return False
    return all(len(p) == 2 and math.isfinite(p[0]) and math.isfinite(p[1]) for p in points)


def check_route_file(path: Path, network: Network) -> None:
    """Edges exist and times are times, for every vehicle, trip, flow and route."""
    owner: list[tuple[str, str]] = []  # open demand elements: (tag, id)
    for event, element in _elements(path):
        tag = element.tag
        if event == "start":
            if tag in _DEMAND:
                owner.append((tag, element.get("id", "?")))
            continue
        if tag in _DEMAND or (tag == "route" and not owner):
            name = f"{tag} '{element.get('id', '?')}'"
        elif owner:
            name = f"{owner[-1][0]} '{owner[-1][1]}'"
        else:
            name = f"{tag} '{element.get('id', '?')}'"
        problem = _problem(element, network)
        if problem is not None:
            raise InputFileError(f"{path}: {name}: {problem}")
        if tag in _DEMAND:
            owner.pop()


def _problem(element: ET.Element, network: Network) -> str | None:
    tag = element.tag
    if tag == "route" and element.get("edges") is not None:
        found = _edges(element.get("edges", ""), network)
        if found:
            return f"route edges: {found}"
    if tag in ("trip", "flow"):
        for attr in ("from", "to", "via"):
            value = element.get(attr)
            if value is not None:
                found = _edges(value, network)
                if found:
                    return f"{attr}: {found}"
    if tag in _DEMAND:
        for attr in ("begin", "end", "depart"):
            value = element.get(attr)
            if value is None or (attr == "depart" and value in _DEPART_WORDS):
                continue
            if not _is_time(value):
                return f"{attr}={value!r} is not a finite time"
    return None


def _edges(value: str, network: Network) -> str | None:
    try:
        network.check_edges_exist(value.split())
    except RouteError as exc:
        return f"{exc}" + (f" ({exc.hint})" if exc.hint else "")
    return None


def _is_time(value: str) -> bool:
    text = value.strip()
    try:
        return math.isfinite(float(text))
    except ValueError:
        return _CLOCK.fullmatch(text) is not None
