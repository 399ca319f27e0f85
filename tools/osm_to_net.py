"""Raw OpenStreetMap -> SUMO network, with the netconvert of the eclipse-sumo wheel.

    python tools/osm_to_net.py sumo:tools/game/racing/spreewaldring.osm -o networks/ring.net.xml
    python tools/osm_to_net.py my_city.osm -o my_city.net.xml --no-guess-tls

The input may be `sumo:<path inside eclipse-sumo>` or a file (.osm or .osm.xml, gzip
allowed). Options are the usual ones for driving studies: ramps and roundabouts guessed,
junctions joined, geometry and lane permissions from OSM, left-hand turn lanes kept.
Anything after `--` is passed to netconvert as is.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from platoon_sumo.sumo.backend import resolve_sumo_path, sumo_binary

#: netconvert options for a drivable road network from OSM (see SUMO's OSM import docs).
OSM_OPTIONS = (
    "--geometry.remove", "--ramps.guess", "--roundabouts.guess", "--junctions.join",
    "--tls.guess-signals", "--tls.discard-simple", "--tls.join", "--tls.default-type", "actuated",
    "--output.street-names", "--output.original-names", "--keep-edges.by-vclass", "passenger",
    "--remove-edges.isolated", "--no-turnarounds.except-deadend",
)  # fmt: skip


def netconvert_command(osm: Path, out: Path, guess_tls: bool, extra: list[str]) -> list[str]:
    cmd = [sumo_binary("netconvert"), "--osm-files", str(osm), "-o", str(out), *OSM_OPTIONS]
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
    cmd = netconvert_command(osm, out, not args.no_guess_tls, extra)
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        print(done.stderr.strip() or done.stdout.strip(), file=sys.stderr)
        return 1
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
