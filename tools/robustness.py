"""Robustness corpus: platoons on many road networks, each run through the command line.

Why: the shipped scenarios were tuned on two networks (docs/real_networks.md); this
harness runs the same platoon set-up on every car network it can find or make, to show
where the co-simulation or the controllers break (crashes, contacts, red lights, stuck
platoons) before a study relies on a new network.

The corpus (`--list` prints it, with the networks left out and why):

- **shipped**: every `*.net.xml` / `*.net.xml.gz` in the eclipse-sumo wheel (the
  `tools/game/` networks, sumolib's RiLSA crossings, ...) that has at least
  `MIN_CAR_ROAD_KM` of road a passenger car may use; a network whose roads, lanes and
  connections equal an earlier one's (only its signal programs differ) is left out as a
  duplicate. The network file is used as shipped (not the games' extra signal files),
  except that a signal phase over 300 s (the games' lights wait for a player, with
  10,000 s greens) is cut to `--signal-cap` s (60) in a copy of its program loaded
  after the network; `--keep-long-phases` runs the programs as shipped.
- **osm**: every OpenStreetMap file in the wheel, converted by `tools/osm_to_net.py`.
- **generated**: netgenerate networks (`GENERATED`): random (`--rand`, several seeds),
  spider and grid, each with priority or right-before-left junctions and with traffic
  lights (`--tls.guess` or `--default-junction-type traffic_light`).
- `--add FILE`: networks of your own (.net.xml[.gz] or .osm[.xml][.gz]).

For each network (seeded by `--seed` and the network's name, so every file is the same
on every run):

1. **platoon routes**: pairs of passenger edges far apart, routed with sumolib's
   fastest path for vClass passenger; routes with a U-turn, a loop, or a first edge
   shorter than `MIN_FIRST_EDGE_M` are rejected; of the rest, those between
   `--min-route` (or 60 % of the longest found, if less) and `--max-route` m that cross
   the most junctions, turns and signals are kept, with distinct first and last edges
   where the network allows. By default the longest is what the last platoon can drive
   before the end at 5 m/s (0.5-2.5 km), the shortest half of that;
2. **background demand**: randomTrips.py for vClass passenger, validated by routing
   (`--validate`, duarouter), one vehicle every `3600 / (--demand * sqrt(car lane km))`
   seconds until the end;
3. **scenario**: `--platoons` platoons of `--members` cars as in
   scenarios/city_platoons.yaml (route-following leader at 11 m/s at most,
   `laser_follower` followers with the `utm30lx` scan and `on_lost: route_following`,
   kinematic bicycle cars, SUMO tau 0.5 s), `actuation` from `--actuation` (default
   `sublane`, the cars' default; `lane` runs without SUMO's sublane model), departing
   every `--stagger` s from `--warmup` s on; checked with `platoon-sumo validate`;
4. **runs**: `platoon-sumo run SCENARIO --out DIR --quiet`, then the same with
   `--no-platoons`, each a child process with a wall-clock limit (`--timeout`), one
   after the other, into `<work>/<network>/with_platoons` and `without_platoons` (their
   stderr, with the runs' warnings, beside them as `.log`).

One table row per network (markdown and CSV in the work folder; `--doc` also rewrites
the block between `<!-- robustness -->` and `<!-- /robustness -->` in
docs/real_networks.md): size, platoon routes, platoon vehicles departed / arrived,
footprint collisions (time, pair and the vehicle at fault, `platoon_sumo.fault`) and
SUMO's collision reports with a platoon car (which side SUMO calls the collider),
red-light violations, platoon cars standing still at the end (for `--gridlock-after`
s, where, and whether before a red light), gridlock events with and without platoons,
teleports, the followers' predecessor-in-view share, human trips finished and their mean
travel time with and without platoons, wall and CPU seconds of both runs, and a status
(`ok`, or what failed with the first line of its error).

Usage::

    python tools/robustness.py --list
    python tools/robustness.py --end 300 --work /tmp/robustness --doc
    python tools/robustness.py --networks cross,grid4_priority --end 90 --platoons 2
    python tools/robustness.py --no-run --work /tmp/inputs   # scenarios only, to inspect

The work folder must be new or empty, or one this tool made (it holds `.robustness`);
the tool never deletes a file, and overwrites only files it wrote there before.
Exit code 0: every network ran; 1: the table is written but a network failed to build
or run; 2: bad input (unknown network, unusable work folder).
"""

from __future__ import annotations

import argparse
import csv
import datetime as dt
import difflib
import gzip
import hashlib
import itertools
import json
import math
import os
import platform
import random
import re
import resource
import shlex
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import IO, Any, cast

import sumo
import sumolib
import yaml

REPO = Path(__file__).resolve().parent.parent
DOC = REPO / "docs" / "real_networks.md"
OSM_TO_NET = Path(__file__).resolve().with_name("osm_to_net.py")
CLI = "import sys; from platoon_sumo.cli import main; sys.exit(main())"
#: File that marks a work folder as made by this tool.
MARKER = ".robustness"
BLOCK_START, BLOCK_END = "<!-- robustness -->", "<!-- /robustness -->"
SECTION = "## Robustness corpus"

STEP_S = 0.1
#: Shipped networks with less car road (edge length, lanes not counted) than this are
#: too small to drive a platoon through several junctions (e.g. the 0.7 km hiking game) [km].
MIN_CAR_ROAD_KM = 1.0
#: Folder names too generic to name a network: the file's stem is added.
GENERIC_FOLDERS = frozenset({"scenarios", "data", "net", "nets", "networks"})
#: A platoon's first edge must hold its leader: 2 m before the end, a car, and slack [m].
MIN_FIRST_EDGE_M = 15.0
#: Pairs of edges drawn per network, and how many of the farthest apart get routed.
PAIRS_DRAWN = 3000
PAIRS_ROUTED = 250
#: Mean speed of a platoon through junctions and lights, for the automatic route length
#: [m/s], and the bounds of that length [m].
PLANNED_SPEED_MPS = 5.0
AUTO_ROUTE_M = (500.0, 2500.0)
#: Pairs farther apart (straight line) than this share of `max_route_m` are not routed:
#: roads wind, so their routes would be longer than that.
STRAIGHT_SHARE = 0.7
#: Shortest background trip, at most this or a quarter of the network's diagonal [m].
MAX_TRIP_MIN_DISTANCE_M = 300.0
#: SUMO's tripinfo and events name a platoon car `<platoon id>.<index>`; ours are `pN`.
PLATOON_PREFIX = "p"
#: A signal phase longer than this holds its red for good in a run of minutes (the
#: games' programs wait for a player: 10,000 s greens); validate warns above it [s].
LONG_PHASE_S = 300.0
#: programID of the shortened copies of such programs.
CAPPED_PROGRAM = "robustness_capped"
#: Status of a network whose inputs were made but not run (`--no-run`).
NOT_RUN = "prepared, not run"
#: The package's default of `outputs.gridlock_after_s` [s].
GRIDLOCK_AFTER_S = 300.0
#: Below this speed a car stands still (SUMO's halting threshold) [m/s].
STILL_MPS = 0.1
#: SUMO link directions that are turns (left, right, partly left, partly right).
TURNS = frozenset("lrLR")


@dataclass(frozen=True)
class Config:
    """Everything that decides the scenarios, fixed per invocation (written to the
    work folder, so a table can be traced to its settings)."""

    end_s: float = 900.0
    seed: int = 42
    platoons: int = 3
    members: int = 4
    actuation: str = "sublane"
    warmup_s: float = 60.0
    stagger_s: float = 30.0
    #: Platoon route length window [m]; None: the longest is what the last platoon can
    #: drive before the end at `PLANNED_SPEED_MPS` (within `AUTO_ROUTE_M`), the shortest
    #: half of it, so that shortened runs still see platoons arrive.
    min_route_m: float | None = None
    max_route_m: float | None = None
    #: Background vehicles an hour per square root of the network's car lane km.
    demand_per_h_sqrt_km: float = 400.0
    #: Standing still this long outside red-light queues is a gridlock (the scenario's
    #: outputs.gridlock_after_s), and a platoon car still standing at the end is stuck
    #: [s]; None: the package's 300 s, or a third of the run if that is shorter.
    gridlock_after_s: float | None = None
    timeout_s: float = 1800.0
    #: Phases longer than `LONG_PHASE_S` are cut to this in a copy of their program that
    #: the scenario loads after the network [s]; None: programs as shipped.
    signal_cap_s: float | None = 60.0

    def still_s(self) -> float:
        if self.gridlock_after_s is not None:
            return self.gridlock_after_s
        return min(GRIDLOCK_AFTER_S, self.end_s / 3.0)

    def route_window_m(self) -> tuple[float, float]:
        longest = self.max_route_m
        if longest is None:
            driving_s = self.end_s - self.warmup_s - self.stagger_s * (self.platoons - 1)
            low, high = AUTO_ROUTE_M
            longest = min(max(PLANNED_SPEED_MPS * driving_s, low), high)
        shortest = 0.5 * longest if self.min_route_m is None else self.min_route_m
        return shortest, longest


@dataclass(frozen=True)
class NetworkSource:
    """Where a network of the corpus comes from."""

    name: str
    kind: str  # "shipped", "osm", "generated", "added"
    #: shipped / osm: the file (`sumo:<path>` shown for files in the wheel); generated:
    #: netgenerate's options.
    origin: str
    file: Path | None = None
    netgenerate_args: tuple[str, ...] = ()


@dataclass(frozen=True)
class LeftOut:
    """A file of the wheel that is not in the corpus, and why."""

    origin: str
    reason: str


@dataclass(frozen=True)
class Route:
    """A platoon route and what it crosses."""

    edges: tuple[str, ...]
    length_m: float
    junctions: int
    signals: int
    turns: int

    @property
    def score(self) -> int:
        return self.junctions + 2 * self.turns + self.signals


@dataclass(frozen=True)
class NetworkSize:
    nodes: int
    edges: int
    car_edges: int
    signalised: int
    car_lane_km: float
    diagonal_m: float


@dataclass(frozen=True)
class RunOutcome:
    """One child run of `platoon-sumo run`."""

    ok: bool
    error: str
    wall_s: float
    cpu_s: float
    summary: dict[str, Any] = field(default_factory=dict)
    in_view_share: float | None = None
    stuck: tuple[str, ...] = ()
    collision_notes: tuple[str, ...] = ()
    sumo_platoon_collider: int = 0
    sumo_platoon_victim: int = 0
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class Row:
    """One network's line of the table (also its CSV row); None: not measured."""

    network: str
    kind: str
    origin: str
    nodes: int | None = None
    edges: int | None = None
    signalised: int | None = None
    car_lane_km: float | None = None
    #: per platoon: route length km / junctions / turns / signalised junctions
    routes: str = ""
    background_vehicles: int | None = None
    planned: int | None = None
    departed: int | None = None
    arrived: int | None = None
    collisions: int | None = None
    collisions_platoon_at_fault: int | None = None
    collision_details: str = ""
    sumo_collisions_with_platoons: int | None = None
    sumo_platoon_collider: int | None = None
    sumo_platoon_victim: int | None = None
    red_lights: int | None = None
    gridlocks: int | None = None
    gridlocks_without: int | None = None
    stuck: int | None = None
    stuck_details: str = ""
    teleports: int | None = None
    emergency_brakings: int | None = None
    #: platoon cars that took a junction in a circle of right of way (`standoff` events)
    standoffs: int | None = None
    in_view_share: float | None = None
    human_finished: int | None = None
    human_finished_without: int | None = None
    human_travel_s: float | None = None
    human_travel_without_s: float | None = None
    wall_with_s: float = 0.0
    cpu_with_s: float = 0.0
    wall_without_s: float = 0.0
    cpu_without_s: float = 0.0
    status: str = "ok"
    notes: str = ""


class BadInput(Exception):
    """A usage error: one line on stderr, exit code 2."""


# --------------------------------------------------------------------------- corpus

#: netgenerate networks: name, options. Every one gets `--seed` (per network) and keeps
#: U-turns only at dead ends. "priority"/"rbl": no lights; "tls": guessed lights at the
#: busier junctions; "alltls": a light at every junction.
GENERATED: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("grid4_priority", ("--grid", "--grid.number", "4", "--grid.length", "200")),
    ("grid4_rbl", ("--grid", "--grid.number", "4", "--grid.length", "150",
                   "--default-junction-type", "right_before_left")),
    ("grid5_tls", ("--grid", "--grid.number", "5", "--grid.length", "200",
                   "--default.lanenumber", "2", "--tls.guess")),
    ("grid4_alltls", ("--grid", "--grid.number", "4", "--grid.length", "250",
                      "--default-junction-type", "traffic_light")),
    ("spider_priority", ("--spider", "--spider.arm-number", "6", "--spider.circle-number", "4",
                         "--spider.space-radius", "150")),
    ("spider_alltls", ("--spider", "--spider.arm-number", "5", "--spider.circle-number", "3",
                       "--spider.space-radius", "200", "--spider.omit-center",
                       "--default-junction-type", "traffic_light")),
    ("rand1_priority", ("--rand", "--rand.iterations", "150")),
    ("rand2_tls", ("--rand", "--rand.iterations", "200", "--tls.guess")),
    ("rand3_alltls", ("--rand", "--rand.iterations", "150",
                      "--default-junction-type", "traffic_light")),
    ("rand4_rbl", ("--rand", "--rand.iterations", "150",
                   "--default-junction-type", "right_before_left")),
    ("rand5_lanes_tls", ("--rand", "--rand.iterations", "200", "--default.lanenumber", "3",
                         "--random-lanenumber", "--tls.guess")),
    ("rand6_grid_priority", ("--rand", "--rand.grid", "--rand.iterations", "200",
                             "--rand.min-distance", "150")),
    ("rand7_grid_alltls", ("--rand", "--rand.grid", "--rand.iterations", "200",
                           "--rand.min-distance", "150",
                           "--default-junction-type", "traffic_light")),
)  # fmt: skip


def sumo_home() -> Path:
    return Path(sumo.SUMO_HOME)


def sumo_bin(name: str) -> str:
    return str(sumo_home() / "bin" / name)


def in_wheel(path: Path) -> str:
    """`sumo:<relative path>` for a file inside eclipse-sumo, else the path."""
    try:
        return "sumo:" + path.resolve().relative_to(sumo_home().resolve()).as_posix()
    except ValueError:
        return str(path)


def read_net(path: Path) -> Any:
    return sumolib.net.readNet(str(path))


def car_edges(net: Any) -> list[Any]:
    return [e for e in net.getEdges() if e.getFunction() == "" and e.allows("passenger")]


def car_lane_km(edges: Iterable[Any]) -> float:
    return sum(ln.getLength() for e in edges for ln in e.getLanes() if ln.allows("passenger")) / 1e3


def layout_key(net: Any) -> str:
    """Hash of the roads, lanes and connections, not the signal programs: networks that
    differ only in their programs (sumolib's RiLSA variants) count once."""
    parts = sorted(
        f"{e.getID()}|{e.getFromNode().getID()}|{e.getToNode().getID()}|{len(e.getLanes())}"
        f"|{e.getLength():.1f}"
        for e in net.getEdges()
    )
    parts += sorted(
        f"{c.getFromLane().getID()}>{c.getToLane().getID()}"
        for e in net.getEdges()
        for conns in e.getOutgoing().values()
        for c in conns
    )
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


def safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "_", text).strip("_") or "net"


def discover_shipped() -> tuple[list[NetworkSource], list[LeftOut]]:
    """Networks and OpenStreetMap files of the wheel, and the files left out."""
    home = sumo_home()
    found = sorted(
        {*home.rglob("*.net.xml"), *home.rglob("*.net.xml.gz")},
        key=lambda p: (p.name in ("net.net.xml", "net.net.xml.gz"), p.as_posix()),
    )
    kept: list[tuple[Path, str]] = []
    left: list[LeftOut] = []
    layouts: dict[str, str] = {}
    for path in found:
        origin = in_wheel(path)
        try:
            net = read_net(path)
        except Exception as exc:  # sumolib raises anything on a broken file
            left.append(LeftOut(origin, f"unreadable ({type(exc).__name__})"))
            continue
        cars = car_edges(net)
        road_km = sum(e.getLength() for e in cars) / 1e3
        if not cars:
            left.append(LeftOut(origin, "no road a passenger car may use"))
            continue
        if road_km < MIN_CAR_ROAD_KM:
            left.append(LeftOut(origin, f"tiny, {road_km * 1000:.0f} m of car roads"))
            continue
        key = layout_key(net)
        if key in layouts:
            left.append(LeftOut(origin, f"same roads as `{layouts[key]}`, other signal programs"))
            continue
        layouts[key] = origin
        kept.append((path, origin))
    names: dict[str, int] = {}
    for path, _ in kept:
        base = safe_name(path.parent.name)
        names[base] = names.get(base, 0) + 1
    sources = []
    for path, origin in kept:
        base = safe_name(path.parent.name)
        stem = path.name.split(".")[0]
        unique = names[base] == 1 and base.lower() not in GENERIC_FOLDERS
        name = base if unique else f"{base}_{safe_name(stem)}"
        sources.append(NetworkSource(name, "shipped", origin, file=path))
    osm = sorted(
        p
        for pattern in ("*.osm", "*.osm.xml", "*.osm.gz", "*.osm.xml.gz")
        for p in home.rglob(pattern)
    )
    for path in osm:
        stem = path.name.split(".")[0]
        sources.append(NetworkSource(f"osm_{safe_name(stem)}", "osm", in_wheel(path), file=path))
    return sources, left


def added_source(text: str) -> NetworkSource:
    path = Path(text).resolve()
    if not path.is_file():
        raise BadInput(f"--add {text}: no such file")
    stem = safe_name(path.name.split(".")[0])
    kind = "osm" if re.search(r"\.osm(\.xml)?(\.gz)?$", path.name) else "added"
    if kind == "added" and not re.search(r"\.net\.xml(\.gz)?$", path.name):
        raise BadInput(f"--add {text}: expected a .net.xml[.gz] or .osm[.xml][.gz] file")
    return NetworkSource(f"added_{stem}", kind, str(path), file=path)


def corpus(added: Sequence[str]) -> tuple[list[NetworkSource], list[LeftOut]]:
    shipped, left = discover_shipped()
    generated = [
        NetworkSource(n, "generated", shlex.join(a), netgenerate_args=a) for n, a in GENERATED
    ]
    return [*shipped, *generated, *(added_source(a) for a in added)], left


def select(sources: list[NetworkSource], wanted: str | None) -> list[NetworkSource]:
    """The networks named in `wanted` (comma-separated, any case), in corpus order."""
    if not wanted:
        return sources
    by_name = {s.name.lower(): s for s in sources}
    names = [w.strip() for w in wanted.split(",") if w.strip()]
    for name in names:
        if name.lower() not in by_name:
            near = difflib.get_close_matches(name.lower(), list(by_name), n=1)
            hint = f" (did you mean '{by_name[near[0]].name}'?)" if near else ""
            raise BadInput(f"--networks: unknown network '{name}'{hint}; `--list` shows the corpus")
    chosen = {n.lower() for n in names}
    return [s for s in sources if s.name.lower() in chosen]


# --------------------------------------------------------------------------- inputs


def first_line(text: str) -> str:
    """The line of a child's output that says what went wrong."""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    for ln in lines:
        if ln.lower().startswith(("error:", "error ")):
            return ln
    if any(ln.startswith("Traceback") for ln in lines):
        return lines[-1]
    return lines[0] if lines else "no message"


def build_network(source: NetworkSource, folder: Path, seed: int) -> Path:
    """The network file of `source` (made in `folder` if it has to be); raises
    RuntimeError with the builder's message when it cannot."""
    if source.kind in ("shipped", "added"):
        assert source.file is not None
        return source.file
    out = folder / "net.net.xml"
    if source.kind == "osm":
        assert source.file is not None
        cmd = [sys.executable, str(OSM_TO_NET), str(source.file), "-o", str(out)]
    else:
        cmd = [
            sumo_bin("netgenerate"), *source.netgenerate_args, "--seed", str(seed),
            "--no-turnarounds.except-deadend", "--output-file", str(out),
        ]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0 or not out.is_file():
        raise RuntimeError(first_line(done.stderr or done.stdout))
    return out


def measure(net: Any) -> NetworkSize:
    edges = [e for e in net.getEdges() if e.getFunction() == ""]
    cars = car_edges(net)
    (x0, y0), (x1, y1) = net.getBBoxXY()
    return NetworkSize(
        nodes=len(net.getNodes()),
        edges=len(edges),
        car_edges=len(cars),
        signalised=sum(1 for n in net.getNodes() if n.getType().startswith("traffic_light")),
        car_lane_km=car_lane_km(cars),
        diagonal_m=math.hypot(x1 - x0, y1 - y0),
    )


def is_junction(node: Any) -> bool:
    """A node where roads meet (not a mere bend in one road): three or more neighbours,
    or a traffic light."""
    neighbours = {e.getFromNode().getID() for e in node.getIncoming()}
    neighbours |= {e.getToNode().getID() for e in node.getOutgoing()}
    neighbours.discard(node.getID())
    return len(neighbours) >= 3 or node.getType().startswith("traffic_light")


def describe(edges: Sequence[Any]) -> Route | None:
    """The route's junctions, signals and turns; None when a car cannot drive it as
    one of our platoons must (U-turn, loop, or a step no car lane connects)."""
    nodes = [edges[0].getFromNode().getID()] + [e.getToNode().getID() for e in edges]
    if len(set(nodes)) != len(nodes):
        return None
    junctions = signals = turns = 0
    for a, b in itertools.pairwise(edges):
        links = [
            c for c in a.getConnections(b)
            if c.getFromLane().allows("passenger") and c.getToLane().allows("passenger")
        ]  # fmt: skip
        if not links or all(c.getDirection() == "t" for c in links):
            return None
        node = a.getToNode()
        if is_junction(node):
            junctions += 1
            signals += node.getType().startswith("traffic_light")
        turns += any(c.getDirection() in TURNS for c in links)
    return Route(
        edges=tuple(e.getID() for e in edges),
        length_m=sum(e.getLength() for e in edges),
        junctions=junctions,
        signals=signals,
        turns=turns,
    )


def platoon_routes(net: Any, count: int, config: Config, rng: random.Random) -> list[Route]:
    """`count` routes with many junctions and turns (see the module docstring); fewer
    distinct ones, repeated in turn, when the network has fewer."""
    cars = car_edges(net)
    firsts = [e for e in cars if e.getLength() >= MIN_FIRST_EDGE_M]
    if not firsts:
        raise RuntimeError(f"no car edge of {MIN_FIRST_EDGE_M:g} m or more to depart from")
    pairs = {(rng.choice(firsts), rng.choice(cars)) for _ in range(PAIRS_DRAWN)}

    def apart(pair: tuple[Any, Any]) -> float:
        (ax, ay), (bx, by) = pair[0].getFromNode().getCoord(), pair[1].getToNode().getCoord()
        return math.hypot(bx - ax, by - ay)

    shortest_m, longest_m = config.route_window_m()
    # farthest apart first, but not so far that every route would be too long; those
    # only when the network has too few others
    limit_m = STRAIGHT_SHARE * longest_m
    ordered = sorted(
        pairs,
        key=lambda p: (apart(p) > limit_m, abs(limit_m - apart(p)), p[0].getID(), p[1].getID()),
    )
    routes = []
    for a, b in ordered[:PAIRS_ROUTED]:
        if a is b:
            continue
        path, _ = net.getFastestPath(a, b, vClass="passenger")
        route = describe(path) if path else None
        if route is not None and route.junctions > 0:
            routes.append(route)
    if not routes:
        raise RuntimeError("no platoon route: no two car edges joined by a route without U-turn")
    longest = max(r.length_m for r in routes)
    shortest = min(shortest_m, 0.6 * longest)
    fitting = [r for r in routes if shortest <= r.length_m <= longest_m]
    fitting = fitting or [r for r in routes if r.length_m >= shortest]
    fitting.sort(key=lambda r: (-r.score, -r.length_m, r.edges))
    chosen: list[Route] = []
    used: set[str] = set()
    for strict in (True, False):
        for r in fitting:
            if len(chosen) == count:
                break
            ends = {r.edges[0], r.edges[-1]}
            if r in chosen or (strict and ends & used):
                continue
            chosen.append(r)
            used |= ends
    return [chosen[i % len(chosen)] for i in range(count)]


def open_xml(path: Path) -> IO[bytes]:
    if path.suffix == ".gz":
        return cast(IO[bytes], gzip.open(path))
    return path.open("rb")


def capped_signals(net_file: Path, folder: Path, cap_s: float) -> tuple[Path | None, int]:
    """An additional file with a copy of each signal program that has a phase longer
    than `LONG_PHASE_S` (durations, and minDur / maxDur of actuated phases, cut to
    `cap_s`), and how many lights it changes; (None, 0) when none has."""
    programs: dict[str, ET.Element] = {}
    with open_xml(net_file) as stream:
        for _, element in ET.iterparse(stream):
            if element.tag == "tlLogic":
                programs[str(element.get("id"))] = element  # the last one loaded runs
            elif element.tag in ("edge", "connection"):
                element.clear()
    root = ET.Element("additional")
    for light in programs.values():
        phases = light.findall("phase")
        if not any(
            float(ph.get(key) or 0.0) > LONG_PHASE_S
            for ph in phases
            for key in ("duration", "maxDur")
        ):
            continue
        light.set("programID", CAPPED_PROGRAM)
        for ph in phases:
            for key in ("duration", "minDur", "maxDur"):
                if ph.get(key) is not None and float(str(ph.get(key))) > LONG_PHASE_S:
                    ph.set(key, f"{cap_s:g}")
            if ph.get("minDur") is not None and float(str(ph.get("minDur"))) > cap_s:
                ph.set("minDur", f"{cap_s:g}")
        light.tail = None
        root.append(light)
    if not len(root):
        return None, 0
    path = folder / "capped_signals.add.xml"
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    return path, len(root)


def background_demand(net_file: Path, folder: Path, size: NetworkSize, config: Config) -> Path:
    """Validated random passenger trips over the whole run (randomTrips.py + duarouter)."""
    period_s = 3600.0 / (config.demand_per_h_sqrt_km * math.sqrt(max(size.car_lane_km, 0.01)))
    trips, routes = folder / "background.trips.xml", folder / "background.rou.xml"
    cmd = [
        sys.executable, str(sumo_home() / "tools" / "randomTrips.py"),
        "-n", str(net_file), "-o", str(trips), "-r", str(routes),
        "--begin", "0", "--end", repr(config.end_s), "--period", f"{period_s:.3f}",
        "--seed", str(config.seed), "--vehicle-class", "passenger", "--validate",
        "--fringe-factor", "5", "--prefix", "bg",
        "--min-distance", f"{min(MAX_TRIP_MIN_DISTANCE_M, size.diagonal_m / 4):.0f}",
        "--trip-attributes", 'departLane="best" departSpeed="max"',
    ]  # fmt: skip
    env = {**os.environ, "SUMO_HOME": str(sumo_home())}
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=folder, check=False)
    if done.returncode != 0 or not routes.is_file():
        raise RuntimeError("randomTrips.py: " + first_line(done.stderr or done.stdout))
    return routes


def scenario(
    name: str,
    net_ref: str,
    additional: Path | None,
    routes_file: Path,
    routes: Sequence[Route],
    config: Config,
) -> dict[str, Any]:
    """The scenario mapping: the city scenario's platoons on this network's routes."""
    platoons = [
        {
            "id": f"{PLATOON_PREFIX}{i}",
            "route": {"edges": list(r.edges)},
            "depart_s": config.warmup_s + config.stagger_s * i,
            "members": config.members,
            "spacing_m": 8.0,
            "actuation": config.actuation,
            "vehicle": {
                "model": "bicycle",
                "length_m": 4.5,
                "width_m": 1.8,
                "wheelbase_m": 2.7,
                "sumo_tau_s": 0.5,
            },
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 11.0}},
            "follower": {
                "type": "laser_follower",
                "params": {"on_lost": "route_following", "corridor_margin_rel": 1.2},
                "sensor": {"preset": "utm30lx"},
            },
        }
        for i, r in enumerate(routes)
    ]
    simulation: dict[str, Any] = {"step_s": STEP_S, "end_s": config.end_s, "seed": config.seed}
    if config.actuation == "lane":
        simulation["lateral_resolution_m"] = None  # SUMO drives every platoon car
    return {
        "name": f"robustness_{name}",
        "description": f"tools/robustness.py: {len(routes)} platoons of {config.members} on {name}",
        "simulation": simulation,
        "network": {
            "net_file": net_ref,
            "additional_files": [str(additional)] if additional else [],
        },
        "traffic": {"route_files": [str(routes_file)]},
        "platoons": platoons,
        "outputs": {"gridlock_after_s": config.still_s()},
    }


# --------------------------------------------------------------------------- runs


def cli(*args: str) -> list[str]:
    return [sys.executable, "-c", CLI, *args]


def run_child(cmd: list[str], cwd: Path, timeout_s: float) -> tuple[int | None, str, float, float]:
    """(exit code or None on timeout, stderr, wall s, CPU s) of one child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    try:
        done = subprocess.run(
            cmd, capture_output=True, text=True, cwd=cwd, timeout=timeout_s, check=False
        )
        code: int | None = done.returncode
        err = done.stderr
    except subprocess.TimeoutExpired as exc:
        code = None
        err = exc.stderr.decode(errors="replace") if isinstance(exc.stderr, bytes) else ""
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return code, err, wall, cpu


@dataclass(frozen=True)
class TrajectoryFacts:
    """What the results need from trajectories.csv."""

    in_view_share: float | None
    #: Platoon cars still in the network at the end that had not moved (0.1 m/s) for
    #: `gridlock_after_s`, with where they stood: the run's gridlock check leaves out
    #: cars queued before a red light, and a light that never turns green keeps them.
    stuck: tuple[str, ...]


def trajectory_facts(path: Path, end_s: float, still_s: float) -> TrajectoryFacts:
    """Followers' mean `predecessor_in_view` (rows with a scan) and stuck platoon cars."""
    if not path.is_file():
        return TrajectoryFacts(None, ())
    seen = total = 0
    last: dict[str, dict[str, str]] = {}
    moved_s: dict[str, float] = {}
    with path.open(newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            value = row.get("predecessor_in_view", "")
            if row.get("role") == "follower" and value != "":
                total += 1
                seen += float(value) > 0
            vehicle, now = row["vehicle_id"], float(row["time_s"])
            if vehicle not in moved_s or float(row["speed_mps"] or 0.0) >= STILL_MPS:
                moved_s[vehicle] = now
            last[vehicle] = row
    stuck = []
    for vehicle, row in last.items():
        now = float(row["time_s"])
        if now < end_s - 1.0 or now - moved_s[vehicle] < still_s:
            continue
        where = f"{vehicle} on {row.get('lane_id') or '?'}"
        if row.get("signal_state", "") in ("r", "R", "u") and row.get("signal_distance_m"):
            where += f" at red {float(row['signal_distance_m']):.0f} m ahead"
        stuck.append(where)
    return TrajectoryFacts(seen / total if total else None, tuple(stuck))


def collision_events(path: Path, platoon_ids: set[str]) -> tuple[list[str], int, int]:
    """Short notes on the footprint collisions, and how often SUMO's own check named a
    platoon car the collider and the victim (events.csv)."""
    if not path.is_file():
        return [], 0, 0

    def ours(vehicle: str) -> bool:
        return vehicle.rsplit(".", 1)[0] in platoon_ids

    notes: list[str] = []
    collider = victim = 0
    with path.open(newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            kind, a, b = row.get("kind"), row.get("vehicle_id", ""), row.get("other_id", "")
            if kind in ("collision", "wall_contact"):
                fault = row.get("at_fault") or "undetermined"
                notes.append(f"{float(row['time_s']):.0f} s {a}×{b or 'wall'}, fault {fault}")
            elif kind == "sumo_collision":
                collider += ours(a)
                victim += ours(b)
    return notes, collider, victim


def run_once(
    scenario_file: Path, out: Path, config: Config, platoon_ids: set[str], baseline: bool
) -> RunOutcome:
    args = ["run", str(scenario_file), "--out", str(out), "--quiet"]
    if baseline:
        args.append("--no-platoons")
    code, err, wall, cpu = run_child(cli(*args), out.parent, config.timeout_s)
    # the run's warnings (long phases, invented junctions, platoons never inserted) stay
    # beside its folder
    (out.parent / f"{out.name}.log").write_text(err, encoding="utf-8")
    warnings = tuple(
        ln[len("warning: ") :] for ln in err.splitlines() if ln.startswith("warning: ")
    )
    summary_file = out / "summary.json"
    if code is None:
        return RunOutcome(
            False, f"timeout after {config.timeout_s:g} s", wall, cpu, warnings=warnings
        )
    if code != 0 or not summary_file.is_file():
        failed = out / "FAILED.txt"
        reason = failed.read_text(encoding="utf-8") if failed.is_file() else err
        return RunOutcome(False, first_line(reason), wall, cpu, warnings=warnings)
    summary = json.loads(summary_file.read_text(encoding="utf-8"))
    notes, collider, victim = collision_events(out / "events.csv", platoon_ids)
    facts = trajectory_facts(out / "trajectories.csv", config.end_s, config.still_s())
    return RunOutcome(
        ok=True,
        error="",
        wall_s=wall,
        cpu_s=cpu,
        summary=summary,
        in_view_share=facts.in_view_share,
        stuck=facts.stuck,
        collision_notes=tuple(notes),
        sumo_platoon_collider=collider,
        sumo_platoon_victim=victim,
        warnings=warnings,
    )


def validate(scenario_file: Path, cwd: Path) -> str | None:
    """None if `platoon-sumo validate` accepts the scenario, else its error line."""
    code, err, _, _ = run_child(cli("validate", str(scenario_file)), cwd, 300.0)
    return None if code == 0 else first_line(err)


def traffic(summary: dict[str, Any]) -> tuple[int | None, float | None]:
    t = summary.get("traffic", {})
    return t.get("human_trips_finished"), t.get("human_mean_travel_time_s")


def shorten(items: Sequence[str], shown: int = 4) -> str:
    more = f"; ... {len(items) - shown} more" if len(items) > shown else ""
    return "; ".join(items[:shown]) + more


def prepare(source: NetworkSource, folder: Path, config: Config) -> tuple[Row, Path | None]:
    """Network, routes, demand and checked scenario file of one network: the row with the
    network's size, and the scenario (None, with the reason in the row's status, when the
    network cannot be built or the scenario is refused)."""
    row = Row(network=source.name, kind=source.kind, origin=source.origin)
    digest = hashlib.sha256(f"{config.seed}:{source.name}".encode()).digest()
    seed = int.from_bytes(digest[:4], "big")
    try:
        net_file = build_network(source, folder, seed % 100_000 + 1)
        net = read_net(net_file)
        size = measure(net)
        row = replace(
            row, nodes=size.nodes, edges=size.edges, signalised=size.signalised,
            car_lane_km=round(size.car_lane_km, 1),
        )  # fmt: skip
        if not size.car_edges:
            raise RuntimeError("no road a passenger car may use")
        routes = platoon_routes(net, config.platoons, config, random.Random(seed))
        demand = background_demand(net_file, folder, size, config)
        signals, capped = None, 0
        if config.signal_cap_s is not None:
            signals, capped = capped_signals(net_file, folder, config.signal_cap_s)
    except Exception as exc:  # a network that cannot be built is a row, not a crash
        reason = (str(exc) or type(exc).__name__).strip().splitlines()[0]
        return replace(row, status=f"build failed: {reason}"), None
    if capped:
        row = replace(
            row,
            notes=f"{capped} lights' phases over {LONG_PHASE_S:g} s cut to "
            f"{config.signal_cap_s:g} s",
        )
    row = replace(
        row,
        routes=", ".join(
            f"{r.length_m / 1e3:.1f}/{r.junctions}/{r.turns}/{r.signals}" for r in routes
        ),
        background_vehicles=demand.read_text(encoding="utf-8").count("<vehicle "),
    )
    net_ref = in_wheel(net_file) if source.kind == "shipped" else str(net_file.resolve())
    data = scenario(source.name, net_ref, signals, demand.resolve(), routes, config)
    scenario_file = folder / "scenario.yaml"
    scenario_file.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    invalid = validate(scenario_file, folder)
    if invalid is not None:
        return replace(row, status=f"invalid scenario: {invalid}"), None
    return row, scenario_file


def with_results(row: Row, cosim: RunOutcome, bare: RunOutcome) -> Row:
    """The row completed with both runs' figures, status and notes."""
    row = replace(
        row, wall_with_s=cosim.wall_s, cpu_with_s=cosim.cpu_s, wall_without_s=bare.wall_s,
        cpu_without_s=bare.cpu_s,
    )  # fmt: skip
    notes = [row.notes] if row.notes else []
    if cosim.ok:
        s = cosim.summary
        pv = s["platoon_vehicles"]
        finished, travel = traffic(s)
        row = replace(
            row,
            planned=pv["planned"],
            departed=pv["departed"],
            arrived=pv["arrived"],
            collisions=s["collisions"],
            collisions_platoon_at_fault=s.get("collisions_platoon_at_fault"),
            collision_details=shorten(cosim.collision_notes),
            sumo_collisions_with_platoons=s["sumo_collisions_with_platoons"],
            sumo_platoon_collider=cosim.sumo_platoon_collider,
            sumo_platoon_victim=cosim.sumo_platoon_victim,
            red_lights=s["red_light_violations"],
            gridlocks=s["gridlocks"],
            stuck=len(cosim.stuck),
            stuck_details=shorten(cosim.stuck, 2),
            teleports=s["teleports"],
            emergency_brakings=s["emergency_brakings"],
            standoffs=s["standoffs"],
            in_view_share=cosim.in_view_share,
            human_finished=finished,
            human_travel_s=travel,
        )
        if s.get("platoons_not_inserted"):
            notes.append("never inserted: " + ", ".join(s["platoons_not_inserted"]))
        if s.get("members_not_inserted"):
            notes.append(f"{len(s['members_not_inserted'])} members still waiting to depart")
        if s.get("removed_off_route"):
            notes.append(f"{len(s['removed_off_route'])} taken out off their route")
        if s["standoffs"]:
            notes.append(f"{s['standoffs']} standoffs (a circle of right of way broken)")
    if bare.ok:
        finished, travel = traffic(bare.summary)
        row = replace(
            row,
            gridlocks_without=bare.summary["gridlocks"],
            human_finished_without=finished,
            human_travel_without_s=travel,
        )
        if bare.summary["gridlocks"]:
            notes.append("gridlocks without platoons")
    if any("longer than" in w or "more long phases" in w for w in cosim.warnings):
        notes.append(f"signal phases over {LONG_PHASE_S:g} s")
    if not cosim.ok:
        status = f"failed: {cosim.error}"
    elif not bare.ok:
        status = f"baseline failed: {bare.error}"
    else:
        status = "ok"
    return replace(row, status=status, notes="; ".join(notes))


def evaluate(source: NetworkSource, work: Path, config: Config, runs: bool = True) -> Row:
    """Build, generate, validate and (with `runs`) run one network; every failure ends
    in the row."""
    folder = work / source.name
    folder.mkdir(parents=True, exist_ok=True)
    row, scenario_file = prepare(source, folder, config)
    if scenario_file is None:
        return row
    if not runs:
        return replace(row, status=NOT_RUN)
    ids = {f"{PLATOON_PREFIX}{i}" for i in range(config.platoons)}
    cosim = run_once(scenario_file, folder / "with_platoons", config, ids, baseline=False)
    bare = run_once(scenario_file, folder / "without_platoons", config, ids, baseline=True)
    return with_results(row, cosim, bare)


# --------------------------------------------------------------------------- report


def fmt(value: float | int | None, digits: int = 0) -> str:
    if value is None:
        return "—"
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}f}"


def pair(a: float | int | None, b: float | int | None, digits: int = 0) -> str:
    return f"{fmt(a, digits)} / {fmt(b, digits)}"


def cell(text: str) -> str:
    """Text safe inside a markdown table cell."""
    return text.replace("|", "\\|").replace("\n", " ")


def markdown_table(rows: Sequence[Row]) -> list[str]:
    lines = [
        "| network | nodes / edges / signalised | platoon routes: km / junctions / turns / "
        "signalised | platoon cars departed / arrived (of) | footprint collisions (platoon car "
        "at fault) | SUMO "
        "collisions with a platoon car (platoon collider / victim) | red lights | platoon cars "
        "stuck at the end | gridlocks with / without platoons | teleports | predecessor in view "
        "| humans finished with / without | human mean travel time with / without [s] "
        "| wall / CPU with, without [s] | status | notes |",
        "|---|---|---|---|---|---|---:|---|---|---:|---:|---|---|---|---|---|",
    ]
    for r in rows:
        collisions = f"{fmt(r.collisions)} ({fmt(r.collisions_platoon_at_fault)})" + (
            f": {r.collision_details}" if r.collision_details else ""
        )
        sumo_col = "—"
        if r.sumo_collisions_with_platoons is not None:
            sumo_col = (
                f"{r.sumo_collisions_with_platoons} "
                f"({r.sumo_platoon_collider} / {r.sumo_platoon_victim})"
            )
        stuck = fmt(r.stuck) + (f" ({r.stuck_details})" if r.stuck_details else "")
        view = "—" if r.in_view_share is None else f"{100 * r.in_view_share:.0f} %"
        moved = f"{fmt(r.departed)} / {fmt(r.arrived)} ({fmt(r.planned)})"
        times = (
            f"{r.wall_with_s:.0f} / {r.cpu_with_s:.0f}, {r.wall_without_s:.0f} / "
            f"{r.cpu_without_s:.0f}"
        )
        lines.append(
            f"| {r.network} | {fmt(r.nodes)} / {fmt(r.edges)} / {fmt(r.signalised)} "
            f"| {r.routes or '—'} | {moved} | {collisions} | {sumo_col} | {fmt(r.red_lights)} "
            f"| {stuck} | {pair(r.gridlocks, r.gridlocks_without)} | {fmt(r.teleports)} "
            f"| {view} | {pair(r.human_finished, r.human_finished_without)} "
            f"| {pair(r.human_travel_s, r.human_travel_without_s)} | {times} | {cell(r.status)} "
            f"| {cell(r.notes)} |"
        )
    return lines


def write_csv(path: Path, rows: Sequence[Row]) -> None:
    names = list(asdict(Row("", "", "")).keys())
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=names)
        writer.writeheader()
        for r in rows:
            writer.writerow({k: "" if v is None else v for k, v in asdict(r).items()})


def code_version() -> str:
    """Commit of the checkout this tool lives in, and whether platoon_sumo/ differs."""

    def git(*args: str) -> str:
        done = subprocess.run(
            ["git", "-C", str(REPO), *args], capture_output=True, text=True, check=False
        )
        return done.stdout.strip() if done.returncode == 0 else ""

    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    if git("status", "--porcelain", "--", "platoon_sumo"):
        commit += " + uncommitted changes in platoon_sumo/"
    return commit


def sumo_version() -> str:
    done = subprocess.run([sumo_bin("sumo"), "--version"], capture_output=True, text=True)
    return done.stdout.splitlines()[0].strip() if done.stdout else "SUMO (unknown version)"


def report(
    rows: Sequence[Row],
    left: Sequence[LeftOut],
    config: Config,
    command: str,
    code: str,
    minutes: float,
) -> str:
    ok = sum(r.status == "ok" for r in rows)
    lines = [
        f"Produced by `{command}` on {dt.date.today().isoformat()} (code {code}, "
        f"{sumo_version()}, Python {platform.python_version()}; {minutes:.0f} min on "
        f"{os.cpu_count()} cores, one run at a time).  ",
        f"Each network: {config.platoons} platoons of {config.members} cars "
        f"(`actuation: {config.actuation}`), departing every {config.stagger_s:g} s from "
        f"{config.warmup_s:g} s, {config.end_s:g} simulated s, seed {config.seed}; gridlock "
        f"and stuck after {config.still_s():g} s standing. {ok} of {len(rows)} networks ran "
        "without failure.",
        "",
        *markdown_table(rows),
    ]
    if left:
        lines += ["", "Files of the wheel left out: " + "; ".join(
            f"`{x.origin}`: {x.reason}" for x in left
        ) + "."]  # fmt: skip
    return "\n".join(lines) + "\n"


def update_doc(path: Path, body: str) -> None:
    """Put `body` between the markers of `path` (a new section at the end if absent)."""
    block = f"{BLOCK_START}\n{body.strip()}\n{BLOCK_END}"
    text = path.read_text(encoding="utf-8") if path.is_file() else "# Platoons on real networks\n"
    i, j = text.find(BLOCK_START), text.find(BLOCK_END)
    if 0 <= i < j:
        text = text[:i] + block + text[j + len(BLOCK_END) :]
    else:
        text = text.rstrip("\n") + f"\n\n{SECTION}\n\n{block}\n"
    path.write_text(text, encoding="utf-8")


# --------------------------------------------------------------------------- main


def prepare_work(text: str | None) -> Path:
    """A work folder the tool may write into: new, empty, or made by this tool."""
    if text is None:
        work = Path(tempfile.mkdtemp(prefix="robustness_"))
    else:
        work = Path(text).resolve()
        if work.exists() and not work.is_dir():
            raise BadInput(f"--work {text}: exists and is not a folder")
        if work.is_dir() and any(work.iterdir()) and not (work / MARKER).is_file():
            raise BadInput(
                f"--work {text}: folder is not empty and was not made by this tool "
                f"(no {MARKER} in it); give a new or empty folder"
            )
        work.mkdir(parents=True, exist_ok=True)
    (work / MARKER).write_text("made by tools/robustness.py\n", encoding="utf-8")
    return work


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    d = Config()
    p.add_argument("--list", action="store_true", help="print the corpus and exit")
    p.add_argument("--no-run", action="store_true", help="make and check the inputs only")
    p.add_argument("--networks", help="comma-separated names (default: the whole corpus)")
    p.add_argument("--add", action="append", default=[], metavar="FILE",
                   help="also run this .net.xml[.gz] or .osm file (repeatable)")  # fmt: skip
    p.add_argument("--work", help="work folder: new, empty or made by this tool (default: temp)")
    p.add_argument("--doc", nargs="?", const=str(DOC), metavar="MD",
                   help=f"rewrite the block in MD (default {DOC.relative_to(REPO)})")  # fmt: skip
    p.add_argument("--end", type=float, default=d.end_s, help="simulated seconds [s]")
    p.add_argument("--seed", type=int, default=d.seed, help="seed of everything")
    p.add_argument("--platoons", type=int, default=d.platoons, help="platoons per network")
    p.add_argument("--members", type=int, default=d.members, help="cars per platoon")
    p.add_argument("--actuation", default=d.actuation, choices=("lane", "sublane", "planar"))
    p.add_argument("--warmup", type=float, default=d.warmup_s, help="first departure [s]")
    p.add_argument("--stagger", type=float, default=d.stagger_s, help="between departures [s]")
    p.add_argument("--min-route", type=float, help="shortest platoon route (default: auto) [m]")
    p.add_argument("--max-route", type=float, help="longest platoon route (default: auto) [m]")
    p.add_argument("--demand", type=float, default=d.demand_per_h_sqrt_km,
                   help="background vehicles an hour per sqrt(car lane km)")  # fmt: skip
    p.add_argument("--gridlock-after", type=float,
                   help="standing still this long is a gridlock or stuck (default: "
                        f"{GRIDLOCK_AFTER_S:g}, at most a third of --end) [s]")  # fmt: skip
    p.add_argument("--timeout", type=float, default=d.timeout_s, help="wall limit per run [s]")
    p.add_argument("--signal-cap", type=float, default=d.signal_cap_s,
                   help=f"cut signal phases over {LONG_PHASE_S:g} s to this [s]")  # fmt: skip
    p.add_argument("--keep-long-phases", action="store_true",
                   help="run the signal programs as shipped")  # fmt: skip
    args = p.parse_args(argv)
    if args.platoons < 1 or args.members < 1:
        p.error("--platoons and --members must be at least 1")
    if args.end <= 0 or args.timeout <= 0:
        p.error("--end and --timeout must be positive")
    return args


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parse_args(argv)
    config = Config(
        end_s=args.end, seed=args.seed, platoons=args.platoons, members=args.members,
        actuation=args.actuation, warmup_s=args.warmup, stagger_s=args.stagger,
        min_route_m=args.min_route, max_route_m=args.max_route, demand_per_h_sqrt_km=args.demand,
        gridlock_after_s=args.gridlock_after, timeout_s=args.timeout,
        signal_cap_s=None if args.keep_long_phases else args.signal_cap,
    )  # fmt: skip
    try:
        sources, left = corpus(args.add)
        chosen = select(sources, args.networks)
        if args.list:
            for s in sources:
                print(f"{s.name:<24} {s.kind:<10} {s.origin}")
            for x in left:
                print(f"{'(left out)':<24} {'':<10} {x.origin}: {x.reason}")
            return 0
        work = prepare_work(args.work)
    except BadInput as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    started = time.perf_counter()
    code = code_version()  # at the start: the runs use the code as it is now
    print(f"work folder: {work}; {len(chosen)} networks", file=sys.stderr, flush=True)
    (work / "config.json").write_text(json.dumps(asdict(config), indent=2) + "\n")
    rows: list[Row] = []
    for k, source in enumerate(chosen, 1):
        row = evaluate(source, work, config, runs=not args.no_run)
        rows.append(row)
        (work / source.name / "row.json").write_text(json.dumps(asdict(row), indent=2) + "\n")
        print(
            f"[{k}/{len(chosen)}] {source.name}: {row.status}; platoon cars "
            f"{fmt(row.arrived)}/{fmt(row.departed)} arrived, {fmt(row.collisions)} collisions "
            f"({fmt(row.collisions_platoon_at_fault)} platoon at fault), "
            f"{fmt(row.red_lights)} red lights, {fmt(row.stuck)} stuck, gridlocks "
            f"{pair(row.gridlocks, row.gridlocks_without)}, "
            f"{row.wall_with_s + row.wall_without_s:.0f} s wall",
            file=sys.stderr,
            flush=True,
        )
    minutes = (time.perf_counter() - started) / 60.0
    tool = os.path.relpath(Path(__file__).resolve())
    command = shlex.join(["python", tool if not tool.startswith("..") else __file__, *argv])
    text = report(rows, left if not args.networks else [], config, command, code, minutes)
    (work / "robustness.md").write_text(text, encoding="utf-8")
    write_csv(work / "robustness.csv", rows)
    print(text)
    print(f"table: {work / 'robustness.md'}, {work / 'robustness.csv'}", file=sys.stderr)
    if args.doc:
        update_doc(Path(args.doc), text)
        print(f"written to {args.doc} (block {BLOCK_START})", file=sys.stderr)
    failed = [r.network for r in rows if r.status not in ("ok", NOT_RUN)]
    if failed:
        print(f"not ok: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
