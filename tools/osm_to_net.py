"""Raw OpenStreetMap -> SUMO network, with the netconvert of the eclipse-sumo wheel.

    python tools/osm_to_net.py sumo:tools/game/racing/spreewaldring.osm -o networks/ring.net.xml
    python tools/osm_to_net.py my_city.osm -o my_city.net.xml --no-guess-tls

The input may be `sumo:<path inside eclipse-sumo>` or a file (.osm or .osm.xml, gzip
allowed). Options are the usual ones for driving studies: ramps and roundabouts guessed,
junctions joined, geometry and lane permissions from OSM, left-hand turn lanes kept.
Road types come from SUMO's OSM type map with the overrides in `osm_car_roads.typ.xml`
beside this tool (cars may use service roads and race circuits). Anything after `--` is
passed to netconvert as is.

netconvert's warnings are summarised on stderr. The network is written to a temporary
file first and moved to the output only when it has roads a car may use; otherwise the
tool says so and exits 1, leaving any existing output file untouched.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

from platoon_sumo.subprocesses import run_tool
from platoon_sumo.sumo.backend import resolve_sumo_path, sumo_binary, sumo_home

#: Our road-type overrides, loaded after SUMO's OSM type map.
CAR_TYPES = Path(__file__).resolve().with_name("osm_car_roads.typ.xml")
#: netconvert warnings shown before "... and N more".
SHOWN_WARNINGS = 5

#: netconvert options for a drivable road network from OSM (see SUMO's OSM import docs).
OSM_OPTIONS = (
    "--geometry.remove", "--ramps.guess", "--roundabouts.guess", "--junctions.join",
    "--tls.guess-signals", "--tls.discard-simple", "--tls.join", "--tls.default-type", "actuated",
    "--output.street-names", "--output.original-names", "--keep-edges.by-vclass", "passenger",
    "--remove-edges.isolated", "--no-turnarounds.except-deadend",
)  # fmt: skip


def netconvert_command(osm: Path, out: Path, guess_tls: bool, extra: list[str]) -> list[str]:
    types = Path(sumo_home()) / "data" / "typemap" / "osmNetconvert.typ.xml"
    cmd = [
        sumo_binary("netconvert"), "--osm-files", str(osm), "-o", str(out),
        "--type-files", f"{types},{CAR_TYPES}", *OSM_OPTIONS,
    ]  # fmt: skip
    if not guess_tls:
        cmd = [c for c in cmd if c not in ("--tls.guess-signals",)]
    return [*cmd, *extra]


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    extra: list[str] = []
    if "--" in argv:
        extra = argv[argv.index("--") + 1 :]
        argv = argv[: argv.index("--")]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("osm", help="OSM file, or sumo:<path in eclipse-sumo>")
    ap.add_argument("-o", "--output", required=True, help="the .net.xml to write")
    ap.add_argument("--no-guess-tls", action="store_true", help="only OSM's own signals")
    args = ap.parse_args(argv)
    osm = resolve_sumo_path(args.osm) if args.osm.startswith("sumo:") else Path(args.osm)
    if not osm.is_file():
        print(f"error: {args.osm}: file not found ({osm})", file=sys.stderr)
        return 2
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(suffix=".net.xml", dir=out.parent, prefix=".osm_to_net_")
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        done = run_tool(netconvert_command(osm, tmp, not args.no_guess_tls, extra))
        report_warnings(done.stderr)
        edges = drivable_edges(tmp) if done.returncode == 0 else 0
        if edges == 0 and (done.returncode == 0 or "No edges loaded" in done.stderr):
            print(
                f"error: {args.osm}: netconvert built no road a car may use (the file has "
                "no highway types that allow passenger cars, or every such road was removed "
                f"as isolated); {out} was not written. Check the OSM file's highway tags, or "
                "pass your own type map after `--` (e.g. -- --type-files my.typ.xml).",
                file=sys.stderr,
            )
            return 1
        if done.returncode != 0:
            error = done.stderr.strip() or done.stdout.strip()
            print(f"error: {args.osm}: netconvert failed: {error}", file=sys.stderr)
            return 1
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    print(f"wrote {out} ({edges} edges a car may use)")
    return 0


def report_warnings(stderr: str) -> None:
    """netconvert's warnings, the first few and how many more."""
    warnings = [line for line in stderr.splitlines() if line.startswith("Warning:")]
    for line in warnings[:SHOWN_WARNINGS]:
        print(f"netconvert {line}", file=sys.stderr)
    if len(warnings) > SHOWN_WARNINGS:
        print(f"netconvert: ... and {len(warnings) - SHOWN_WARNINGS} more warnings",
              file=sys.stderr)  # fmt: skip


def drivable_edges(net: Path) -> int:
    """Normal (not internal) edges with a lane that allows passenger cars."""
    count = 0
    for _, elem in ET.iterparse(net, events=("end",)):
        if elem.tag == "edge" and elem.get("function") is None:
            if any(_allows_cars(lane) for lane in elem.iter("lane")):
                count += 1
            elem.clear()
    return count


def _allows_cars(lane: ET.Element) -> bool:
    allow, disallow = lane.get("allow"), lane.get("disallow")
    if allow is not None:
        return "passenger" in allow.split() or allow == "all"
    return disallow is None or "passenger" not in disallow.split()


if __name__ == "__main__":
    sys.exit(main())
