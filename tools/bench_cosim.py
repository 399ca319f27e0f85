"""CPU cost of the co-simulation loop against SUMO alone, through the command line only.

Builds a 10 x 10 signalised grid (netgenerate, 250 m blocks, 2 lanes each way) and ONE
background demand (randomTrips.py with a fixed seed, routed once by duarouter into a
route file: a dense burst during the warm-up, then a steady rate, about 2,000-2,500
SUMO vehicles in the network), then runs, for each end time used:

- **SUMO alone**: the `sumo` binary on the same net and route file with the options and
  outputs the co-simulation asks SUMO for (below);
- **no platoons**: `platoon-sumo run SCENARIO --out DIR --quiet --no-platoons`;
- **co-simulation** with K platoons of 5 cars (route-following leader, 4
  `laser_follower`s with a UTM-30LX scan, `actuation: lane`, kinematic bicycle cars),
  each starting on its own edge picked anywhere in the grid with a seeded generator,
  heading to an edge at least `--min-route` m away (Manhattan), departing one after the
  other over `--stagger` s after the warm-up: `platoon-sumo run SCENARIO --out DIR
  --quiet`.

Every run is a child process (`python -c "...platoon_sumo.cli.main()" run ...`), so the
bench uses no Python API of the package and measures the code installed for
`sys.executable`, whatever its internals. CPU = user + system seconds of the whole child
(`getrusage(RUSAGE_CHILDREN)` deltas: start-up, imports, the loop, post-processing and
writing the outputs). Platoon vehicle-steps = data rows of `trajectories.csv`; the cost
of a platoon vehicle per step = (CPU co-sim - CPU no-platoons at the same end time) /
vehicle-steps. The table goes to stdout and into `docs/performance.md`, section
"## Co-simulation loop", between `<!-- bench_cosim:LABEL -->` and
`<!-- /bench_cosim:LABEL -->` (only that block is replaced), so a "before" and an
"after" table can stand side by side.

SUMO alone runs `sumo` with, mirroring `SumoOptions.command` (platoon_sumo/sumo/backend.py)
and `sumo_output_args` / `write_edgedata_additional` (platoon_sumo/metrics/sumo_outputs.py)
for a scenario with `lateral_resolution_m: null`, no demand scale and default outputs::

    --net-file NET --step-length 0.1 --begin 0.0 --seed SEED --time-to-teleport -1
    --collision.action warn --collision.check-junctions true --no-step-log true
    --no-warnings true --collision.mingap-factor 0 --duration-log.disable true
    --xml-validation never --route-files ROUTES
    --additional-files inputs/edgedata.add.xml    (<edgeData period="60"> -> edgedata.csv)
    --tripinfo-output tripinfo.csv --tripinfo-output.write-unfinished true
    --statistic-output sumo_statistics.xml
    --device.emissions.probability 1 --summary-output sumo_summary.csv
    --personinfo-output personinfo.csv
    --end END

(the co-simulation stops at END by its own loop instead of `--end`).

Usage::

    python tools/bench_cosim.py --label before                 # all cases, writes the docs
    python tools/bench_cosim.py --end 30 --cases 0,10 --no-doc # a quick smoke run
    python tools/bench_cosim.py --cases 0,10,50,100,500 --budget-min 40 --label after

`--cases` are platoon vehicle counts (multiples of 5); the 500 case runs with `--end-500`
(and so do its own SUMO-alone and no-platoons baselines). `--budget-min` skips the cases
not yet started once the bench has run that long (they are reported as not measured).
`--timings` adds, below the table, each case's CPU by stage from one more, untimed run
with `platoon-sumo run --timings` (the timed runs never read the stage clock), made at
the same time as a `--no-platoons --timings` run of the same traffic (one on each core,
so that both see the same host load); it also gives how much longer SUMO's step takes
with the platoon cars, per platoon vehicle-step: a part of the bench's figure that is
not the loop's; and the bench's figure itself from those two whole processes (each
child's own CPU), which the host's drift between the table's runs does not move. It
then runs SUMO alone beside the co-simulation without platoons, for the no-platoons
ratio under the same host load.
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib.metadata
import json
import math
import os
import platform
import random
import re
import resource
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlparse

import pandas as pd
import sumo
import yaml

from platoon_sumo.loop.timing import OUTSIDE, SUMO

MEMBERS = 5
STEP_S = 0.1
EDGEDATA_PERIOD_S = 60.0
CLI = "import sys; from platoon_sumo.cli import main; sys.exit(main())"
SECTION = "## Co-simulation loop"
DOC = Path(__file__).resolve().parent.parent / "docs" / "performance.md"
INTRO = """\
Measured by `tools/bench_cosim.py` (method and SUMO options in its docstring): the CPU
time (user + system) of whole `platoon-sumo run` processes on a 10 x 10 signalised grid
(netgenerate, 250 m blocks, 2 lanes each way) with one fixed background demand from
randomTrips.py, routed once (a burst during a 20 s warm-up, then a steady rate: about
2,000-2,500 SUMO vehicles in the network), against the `sumo` binary alone on the same
net, route file, seed, options and outputs, and against `platoon-sumo run --no-platoons`
(the same traffic through the co-simulation without platoons). Platoons: 5 cars each
(route-following leader, 4 `laser_follower`s with a UTM-30LX scan and `on_lost:
route_following`, `actuation: lane`, SUMO tau 0.5 s), each from its own first edge
anywhere in the grid to an edge at least 2 km away, departing one after the other in the
20 s after the warm-up. "µs CPU / platoon vehicle-step" = (CPU co-sim - CPU no-platoons
at the same end time) / rows of `trajectories.csv` (one row per platoon vehicle per
step). A short untimed co-simulation runs first, so that numba's kernels are compiled and
cached before any timed run (since session 25). Each labelled block below is rewritten by
a run of the bench with that `--label`."""


@dataclass
class Run:
    """One measured child process."""

    name: str
    end_s: float
    cpu_s: float
    wall_s: float
    directory: Path
    summary: dict[str, Any] = field(default_factory=dict)
    sumo_mean: float | None = None
    sumo_max: int | None = None
    vehicle_steps: int = 0


# --------------------------------------------------------------------------- inputs


def sumo_bin(name: str) -> str:
    return os.path.join(sumo.SUMO_HOME, "bin", name)


def build_grid(folder: Path, n: int, block_m: float) -> Path:
    net = folder / "grid.net.xml"
    subprocess.run([
        sumo_bin("netgenerate"), "--grid",
        "--grid.number", str(n), "--grid.length", repr(block_m),
        "--default.lanenumber", "2", "--tls.guess", "true", "--no-turnarounds",
        "--seed", "1", "--output-file", str(net),
    ], check=True, capture_output=True)  # fmt: skip
    return net


def build_demand(folder: Path, net: Path, args: argparse.Namespace, end_s: float) -> Path:
    """Route file of the background traffic: `--warmup` s at `--warmup-period`, then
    `--period` until `end_s` (randomTrips.py splits [0, end] into equal intervals, one per
    period given)."""
    intervals = max(1, math.ceil(end_s / args.warmup))
    periods = [args.warmup_period] + [args.period] * (intervals - 1)
    trips, routes = folder / "background.trips.xml", folder / "background.rou.xml"
    cmd = [
        sys.executable, os.path.join(sumo.SUMO_HOME, "tools", "randomTrips.py"),
        "-n", str(net), "-o", str(trips), "-r", str(routes),
        "--begin", "0", "--end", repr(intervals * args.warmup),
        "--period", *(repr(p) for p in periods),
        "--seed", str(args.seed), "--min-distance", repr(args.min_trip),
        "--random-departpos", "--validate", "--prefix", "bg",
        "--trip-attributes", 'departLane="best" departSpeed="max"',
    ]  # fmt: skip
    env = {**os.environ, "SUMO_HOME": str(sumo.SUMO_HOME)}
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=folder, check=False)
    if done.returncode != 0 or not routes.is_file():
        raise SystemExit(f"randomTrips.py failed: {done.stderr.strip() or done.stdout.strip()}")
    return routes


def grid_edges(net: Path) -> dict[str, tuple[tuple[float, float], tuple[float, float]]]:
    """{edge id: (xy of its from-junction, xy of its to-junction)} of the normal edges."""
    root = ET.parse(net).getroot()
    xy = {j.get("id"): (float(j.get("x", 0)), float(j.get("y", 0))) for j in root.iter("junction")}
    return {
        str(e.get("id")): (xy[e.get("from")], xy[e.get("to")])
        for e in root.iter("edge")
        if e.get("function") is None
    }


def platoon_routes(net: Path, count: int, min_route_m: float, seed: int) -> list[tuple[str, str]]:
    """`count` (first edge, last edge) pairs: distinct first edges anywhere in the grid,
    each last edge at least `min_route_m` away (Manhattan, junction to junction)."""
    edges = grid_edges(net)
    rng = random.Random(seed)
    firsts = sorted(edges)
    rng.shuffle(firsts)
    if count > len(firsts):
        raise SystemExit(f"{count} platoons need {count} first edges; the grid has {len(firsts)}")
    routes = []
    for first in firsts[:count]:
        start = edges[first][0]
        far = [
            e for e, (_, end) in sorted(edges.items())
            if abs(end[0] - start[0]) + abs(end[1] - start[1]) >= min_route_m
        ]  # fmt: skip
        if not far:
            raise SystemExit(f"no edge {min_route_m:g} m away from {first}: lower --min-route")
        routes.append((first, rng.choice(far)))
    return routes


def scenario(
    name: str,
    net: Path,
    routes_file: Path,
    routes: list[tuple[str, str]],
    args: argparse.Namespace,
    end_s: float,
) -> dict[str, Any]:
    k = len(routes)
    platoons = [
        {
            "id": f"p{i:03d}",
            "route": {"from_edge": first, "to_edge": last},
            "depart_s": round(args.warmup + args.stagger * i / k, 3),
            "members": MEMBERS,
            "spacing_m": 8.0,
            "actuation": "lane",
            "vehicle": {
                "model": "bicycle",
                "length_m": 4.5,
                "width_m": 1.8,
                "wheelbase_m": 2.7,
                "sumo_tau_s": 0.5,
            },
            "leader": {"type": "route_following"},
            "follower": {
                "type": "laser_follower",
                "params": {"on_lost": "route_following"},
                "sensor": {"preset": "utm30lx"},
            },
        }
        for i, (first, last) in enumerate(routes)
    ]
    return {
        "name": name,
        "simulation": {
            "step_s": STEP_S, "end_s": end_s, "seed": args.seed, "lateral_resolution_m": None,
        },
        "network": {"net_file": str(net)},
        "traffic": {"route_files": [str(routes_file)]},
        "platoons": platoons,
        "outputs": {"edgedata_period_s": EDGEDATA_PERIOD_S},
    }  # fmt: skip


# --------------------------------------------------------------------------- runs


def measure(cmd: list[str]) -> tuple[float, float]:
    """(CPU user + system, wall) seconds of one child process; exits if it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(
            f"failed ({done.returncode}): {shlex.join(cmd)}\n{done.stderr.strip()[-3000:]}"
        )
    if done.stderr.strip():
        print(f"    {done.stderr.strip()[-1000:]}", flush=True)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def sumo_alone_command(net: Path, routes: Path, out: Path, seed: int, end_s: float) -> list[str]:
    """SUMO as the co-simulation starts it, with its outputs, run by the binary to `end_s`."""
    inputs = out / "inputs"
    inputs.mkdir(parents=True, exist_ok=True)
    additional = inputs / "edgedata.add.xml"
    additional.write_text(
        "<additional>\n"
        f'    <edgeData id="platoon_sumo" file="{(out / "edgedata.csv").as_posix()}" '
        f'period="{EDGEDATA_PERIOD_S:g}"/>\n'
        "</additional>\n",
        encoding="utf-8",
    )
    return [
        sumo_bin("sumo"),
        "--net-file", str(net),
        "--step-length", repr(STEP_S),
        "--begin", repr(0.0),
        "--seed", str(seed),
        "--time-to-teleport", "-1",
        "--collision.action", "warn",
        "--collision.check-junctions", "true",
        "--no-step-log", "true",
        "--no-warnings", "true",
        "--collision.mingap-factor", "0",
        "--duration-log.disable", "true",
        "--xml-validation", "never",
        "--route-files", str(routes),
        "--additional-files", str(additional),
        "--tripinfo-output", str(out / "tripinfo.csv"),
        "--tripinfo-output.write-unfinished", "true",
        "--statistic-output", str(out / "sumo_statistics.xml"),
        "--device.emissions.probability", "1",
        "--summary-output", str(out / "sumo_summary.csv"),
        "--personinfo-output", str(out / "personinfo.csv"),
        "--end", repr(end_s),
    ]  # fmt: skip


def cli(*args: str) -> list[str]:
    return [sys.executable, "-c", CLI, *args]


def sumo_counts(directory: Path) -> tuple[float | None, int | None]:
    """Mean and max of SUMO's running vehicles over the run (its summary output)."""
    path = directory / "sumo_summary.csv"
    if not path.is_file():
        found = sorted(directory.glob("*summary*.csv"))
        if not found:
            return None, None
        path = found[0]
    with path.open(encoding="utf-8") as f:
        header = f.readline().strip().split(";")
        col = next((i for i, c in enumerate(header) if c.endswith("running")), None)
        if col is None:
            return None, None
        values = [int(float(line.split(";")[col])) for line in f if line.strip()]
    if not values:
        return None, None
    return sum(values) / len(values), max(values)


def data_rows(path: Path) -> int:
    """Lines of a CSV file after its header (0 if there is none)."""
    if not path.is_file():
        return 0
    lines = 0
    last = b"\n"
    with path.open("rb") as f:
        while chunk := f.read(1 << 20):
            lines += chunk.count(b"\n")
            last = chunk[-1:]
    if last != b"\n":
        lines += 1
    return max(0, lines - 1)


@dataclass(frozen=True)
class Job:
    name: str
    end_s: float
    directory: Path
    command: Callable[[], list[str]]


def interleaved(jobs: Sequence[Job], repeat: int) -> list[Run]:
    """Run every job `repeat` times, one round of all jobs after the other (so a slow
    spell of this shared host falls on every job alike, not on one); keep each job's
    fastest CPU and wall times and read its last run's outputs."""
    best = [(math.inf, math.inf) for _ in jobs]
    for i in range(repeat):
        for k, job in enumerate(jobs):
            shutil.rmtree(job.directory, ignore_errors=True)
            cpu, wall = measure(job.command())
            best[k] = (min(best[k][0], cpu), min(best[k][1], wall))
            more = f" (round {i + 1}/{repeat})" if repeat > 1 else ""
            print(f"  {job.name:<28} end {job.end_s:5.0f} s: CPU {cpu:8.1f} s, "
                  f"wall {wall:8.1f} s{more}", flush=True)  # fmt: skip
    runs = []
    for job, (cpu, wall) in zip(jobs, best, strict=True):
        run = Run(job.name, job.end_s, cpu, wall, job.directory)
        summary = job.directory / "summary.json"
        if summary.is_file():
            run.summary = json.loads(summary.read_text(encoding="utf-8"))
        run.sumo_mean, run.sumo_max = sumo_counts(job.directory)
        run.vehicle_steps = data_rows(job.directory / "trajectories.csv")
        runs.append(run)
    return runs


# --------------------------------------------------------------------------- report


def git(folder: Path, *args: str) -> str | None:
    try:
        done = subprocess.run(
            ["git", "-C", str(folder), *args], capture_output=True, text=True, check=False
        )
    except OSError:
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def code_measured() -> tuple[str, str]:
    """(git commit, where it is) of the platoon_sumo that the runs import (children of
    `sys.executable` started in the current folder): the checkout it lives in (editable
    install), or the folder pip installed it from."""
    find = "import importlib.util as u; s = u.find_spec('platoon_sumo'); print(s and s.origin)"
    done = subprocess.run([sys.executable, "-c", find], capture_output=True, text=True)
    origin = done.stdout.strip()
    if done.returncode != 0 or origin in ("", "None"):
        return "unknown", "platoon_sumo not found"
    package = Path(origin).resolve().parent
    where = str(package)
    checkouts = []
    top = git(package, "rev-parse", "--show-toplevel")
    if top is not None:
        checkouts.append(Path(top))
    try:
        direct = importlib.metadata.distribution("platoon-sumo").read_text("direct_url.json")
    except importlib.metadata.PackageNotFoundError:
        direct = None
    url = json.loads(direct).get("url", "") if direct else ""
    if url.startswith("file://") and top is None:
        source = Path(unquote(urlparse(url).path))
        where = f"{package}, installed from {source}"
        top = git(source, "rev-parse", "--show-toplevel")
        if top is not None:
            checkouts.append(Path(top))
    for checkout in checkouts:
        commit = git(checkout, "rev-parse", "--short", "HEAD") or "unknown"
        if git(checkout, "status", "--porcelain", "--", "platoon_sumo"):
            commit += " + uncommitted changes in platoon_sumo/"
        return commit, where
    return "unknown", where


def machine() -> str:
    model = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    return f"{model}, {platform.machine()}, {os.cpu_count()} cores, {platform.system()} " \
           f"{platform.release()}"  # fmt: skip


def sumo_version() -> str:
    done = subprocess.run([sumo_bin("sumo"), "--version"], capture_output=True, text=True)
    return done.stdout.splitlines()[0].strip() if done.stdout else "unknown"


def fmt(value: float | None, digits: int = 1) -> str:
    return "—" if value is None else f"{value:,.{digits}f}"


def table(
    cases: list[int],
    skipped: list[int],
    alone: dict[float, Run],
    bare: dict[float, Run],
    cosim: dict[int, Run],
    end_for: dict[int, float],
) -> list[str]:
    lines = [
        "| platoon vehicles | end [s] | SUMO vehicles mean / max | platoon vehicles departed "
        "/ arrived | platoon vehicle-steps | CPU SUMO alone [s] | CPU no-platoons [s] | CPU "
        "co-sim [s] | co-sim / SUMO alone | no-platoons / SUMO alone | µs CPU / platoon "
        "vehicle-step | collisions (platoon / SUMO) | platoons not inserted |",
        "|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|",
    ]
    ends = sorted({end_for[c] for c in cases}, reverse=True)
    rows: list[tuple[int, float]] = []
    for end in ends:
        rows.append((0, end))
        rows += [(c, end) for c in cases if c and end_for[c] == end]
    for n, end in rows:
        if n in skipped:
            lines.append(f"| {n} | {end:g} | not measured (time budget) " + "| " * 10 + "|")
            continue
        a, b = alone.get(end), bare.get(end)
        if a is None or b is None:
            continue
        run = cosim.get(n, b) if n else b
        s = run.summary
        pv = s.get("platoon_vehicles", {})
        per_step = None
        if n and run.vehicle_steps:
            per_step = (run.cpu_s - b.cpu_s) / run.vehicle_steps * 1e6
        counts = f"{fmt(run.sumo_mean, 0)} / {run.sumo_max if run.sumo_max is not None else '—'}"
        moved = f"{pv.get('departed', '—')} / {pv.get('arrived', '—')}" if n else "—"
        crashes = f"{s.get('collisions', '—')} / {s.get('sumo_collisions', '—')}"
        lines.append(
            f"| {n} | {end:g} | {counts} | {moved} | {run.vehicle_steps:,} | {a.cpu_s:.1f} | "
            f"{b.cpu_s:.1f} | {run.cpu_s:.1f} | {run.cpu_s / a.cpu_s:.2f} | "
            f"{b.cpu_s / a.cpu_s:.2f} | {fmt(per_step, 0)} | {crashes} | "
            f"{len(s.get('platoons_not_inserted', []))} |"
        )
    return lines


def stage_timings(cosim: dict[int, Run], scenarios: dict[int, Path], results: Path) -> list[str]:
    """One more (untimed) run of each measured case with `--timings`, side by side with a
    `--no-platoons --timings` run of the same traffic (one on each core, so that both see
    the same host load): its costliest parts per platoon vehicle-step, and how much
    longer SUMO's step takes with the platoon cars than without, as lines for the
    block."""
    lines = [
        "",
        "CPU per platoon vehicle-step by part (one more run of each case with `platoon-sumo "
        "run --timings`, not timed, at the same time as one with `--no-platoons "
        "--timings`; docs/outputs.md, `timings.csv`):",
    ]
    for c, r in cosim.items():
        outs = {"with": results / f"timings_{c}", "without": results / f"timings_{c}_bare"}
        print(f"timings: {c} platoon vehicles, and without them", flush=True)
        commands = {
            "with": cli("run", str(scenarios[c]), "--end", repr(r.end_s)),
            "without": cli("run", str(scenarios[c]), "--no-platoons", "--end", repr(r.end_s)),
        }
        for name, out in outs.items():
            shutil.rmtree(out, ignore_errors=True)
            commands[name] += ["--out", str(out), "--quiet", "--timings"]
        cpu_s = side_by_side(commands, results / f"timings_{c}")
        parts = pd.read_csv(outs["with"] / "timings.csv")
        bare = pd.read_csv(outs["without"] / "timings.csv")
        ours = parts[~parts["kind"].isin([SUMO, OUTSIDE])]
        sumo = parts[parts["kind"] == SUMO]
        step_s, bare_step_s = sumo["cpu_s"].sum(), bare.loc[bare["kind"] == SUMO, "cpu_s"].sum()
        # the platoon vehicle-steps, from SUMO's step: its CPU over its cost per one
        vehicle_steps = step_s / sumo["us_per_platoon_vehicle_step"].sum() * 1e6
        extra_us = (step_s - bare_step_s) / vehicle_steps * 1e6
        per = parts.set_index("part")["us_per_platoon_vehicle_step"]
        shown = ", ".join(f"{name} {per[name]:.1f}" for name in parts["part"].head(9))
        paired_us = (cpu_s["with"] - cpu_s["without"]) / max(r.vehicle_steps, 1) * 1e6
        lines.append(
            f"- {c} platoon vehicles: the whole processes side by side {paired_us:.0f} µs "
            f"({cpu_s['with']:.1f} against {cpu_s['without']:.1f} s, the table's measure "
            f"with both runs under the same host load); the loop's own "
            f"{ours['us_per_platoon_vehicle_step'].sum():.0f} µs; SUMO's step "
            f"{extra_us:.0f} µs more than without the platoon cars ({step_s:.1f} against "
            f"{bare_step_s:.1f} s); {shown} µs"
        )
    return lines


def side_by_side(commands: dict[str, list[str]], logs: Path) -> dict[str, float]:
    """Run the commands at the same time (one on each core, so that all see the same host
    load) and return each one's own CPU time [s] (its log: `logs` with the name added)."""
    running = {}
    for name, command in commands.items():
        with Path(f"{logs}_{name}.log").open("w") as log:
            running[name] = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
    cpu_s = {}
    for name, process in running.items():  # every child waited for, failed or not
        # each child's own CPU (they run at once: not the children's total)
        _, status, usage = os.wait4(process.pid, 0)
        process.returncode = os.waitstatus_to_exitcode(status)
        cpu_s[name] = usage.ru_utime + usage.ru_stime
    for name, process in running.items():
        if process.returncode != 0:
            output = Path(f"{logs}_{name}.log").read_text(encoding="utf-8")
            raise SystemExit(f"run '{name}' failed: {output.strip()}")
    return cpu_s


def baselines_side_by_side(
    scenarios: dict[float, Path], sumo_alone: Callable[[Path, float], list[str]], results: Path
) -> list[str]:
    """SUMO alone and the co-simulation without platoons (of `scenarios`, by end time)
    run at the same time: the table's no-platoons ratio with both under the same host
    load."""
    lines = []
    for end, scenario in scenarios.items():
        outs = {
            "alone": results / f"paired_alone_{end:g}",
            "bare": results / f"paired_bare_{end:g}",
        }
        print(f"side by side: SUMO alone and no platoons, {end:g} s", flush=True)
        for out in outs.values():
            shutil.rmtree(out, ignore_errors=True)
        cpu_s = side_by_side(
            {
                "alone": sumo_alone(outs["alone"], end),
                "bare": cli("run", str(scenario), "--out", str(outs["bare"]), "--quiet",
                            "--no-platoons", "--end", repr(end)),
            },
            results / f"paired_{end:g}",
        )  # fmt: skip
        lines.append(
            f"- no platoons against SUMO alone ({end:g} s), the two side by side: "
            f"{cpu_s['bare'] / cpu_s['alone']:.2f}x ({cpu_s['bare']:.1f} against "
            f"{cpu_s['alone']:.1f} s)"
        )
    return lines


def update_doc(path: Path, label: str, body: str) -> None:
    """Put `body` between the label's markers in the co-simulation section of `path`."""
    start, end = f"<!-- bench_cosim:{label} -->", f"<!-- /bench_cosim:{label} -->"
    block = f"{start}\n{body.strip()}\n{end}"
    text = path.read_text(encoding="utf-8") if path.is_file() else "# Performance\n"
    i, j = text.find(start), text.find(end)
    if 0 <= i < j:
        text = text[:i] + block + text[j + len(end) :]
    else:
        if SECTION not in text.splitlines():
            text = text.rstrip("\n") + f"\n\n{SECTION}\n\n{INTRO}\n"
        at = text.index(SECTION + "\n") + len(SECTION) + 1
        following = re.search(r"^## ", text[at:], flags=re.MULTILINE)
        cut = at + following.start() if following else len(text)
        head, tail = text[:cut].rstrip("\n"), text[cut:]
        text = head + "\n\n" + block + "\n" + ("\n" + tail if tail else "")
    path.write_text(text, encoding="utf-8")


# --------------------------------------------------------------------------- main


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--cases",
        default="0,10,50,100,500",
        help="platoon vehicle counts, multiples of 5 (default: %(default)s)",
    )
    parser.add_argument("--end", type=float, default=300.0, help="simulated seconds [s]")
    parser.add_argument(
        "--end-500",
        type=float,
        default=120.0,
        help="simulated seconds of the 500 case and its baselines [s]",
    )
    parser.add_argument(
        "--repeat", type=int, default=1,
        help="rounds over the baselines and cases of each end time; the minimum counts",
    )  # fmt: skip
    parser.add_argument("--work", help="work folder (default: a temporary one)")
    parser.add_argument("--keep", action="store_true", help="keep the results folders")
    parser.add_argument("--label", default="current", help="name of the block in the docs")
    parser.add_argument("--doc", default=str(DOC), help="markdown file to write the table into")
    parser.add_argument("--no-doc", action="store_true", help="print the table only")
    parser.add_argument(
        "--budget-min",
        type=float,
        help="skip the end times (with their cases) not started after this many minutes; "
        "checked between end times, so it cannot stop the cases of one end time",
    )
    parser.add_argument(
        "--timings", action="store_true",
        help="after the timed rounds, one more run of each case with `platoon-sumo run "
        "--timings` (not timed), beside one with `--no-platoons --timings`: the CPU of each "
        "stage and SUMO's extra step, reported below the table",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=42, help="SUMO, demand and route seed")
    parser.add_argument("--grid", type=int, default=10, help="junctions per side")
    parser.add_argument("--block", type=float, default=250.0, help="block length [m]")
    parser.add_argument(
        "--warmup",
        type=float,
        default=20.0,
        help="warm-up with the dense insertion; platoons depart after it [s]",
    )
    parser.add_argument(
        "--warmup-period",
        type=float,
        default=0.009,
        help="background departure period during the warm-up [s]",
    )
    parser.add_argument(
        "--period",
        type=float,
        default=0.5,
        help="background departure period after the warm-up [s]",
    )
    parser.add_argument(
        "--min-trip",
        type=float,
        default=1500.0,
        help="shortest background trip, randomTrips --min-distance [m]",
    )
    parser.add_argument(
        "--min-route",
        type=float,
        default=2000.0,
        help="shortest platoon route, Manhattan distance [m]",
    )
    parser.add_argument(
        "--stagger",
        type=float,
        default=20.0,
        help="platoon departures spread over this long after the warm-up [s]",
    )
    args = parser.parse_args(argv)
    cases = sorted({int(c) for c in args.cases.split(",") if c.strip()})
    if any(c < 0 or c % MEMBERS for c in cases):
        parser.error(f"--cases: platoon vehicle counts must be multiples of {MEMBERS}")
    if 0 not in cases:
        cases.insert(0, 0)
    end_for = {c: args.end_500 if c >= 500 else args.end for c in cases}
    started = time.perf_counter()
    owned = args.work is None
    work = Path(args.work or tempfile.mkdtemp(prefix="bench_cosim_")).resolve()
    work.mkdir(parents=True, exist_ok=True)
    print(f"work folder: {work}", flush=True)
    # `python -c` puts the current folder first on sys.path: run from the work folder so
    # the runs import the installed platoon_sumo, not a checkout the bench is started in
    doc, tool = Path(args.doc).resolve(), os.path.relpath(Path(__file__).resolve())
    if tool.startswith(".."):
        tool = str(Path(__file__).resolve())
    os.chdir(work)
    commit, where = code_measured()
    print(f"code measured: {where} (commit {commit}); python {sys.executable}", flush=True)

    net = build_grid(work, args.grid, args.block)
    routes_file = build_demand(work, net, args, max(end_for.values()))
    background = sum(1 for line in routes_file.open() if "<vehicle " in line)
    most = max(cases) // MEMBERS
    routes = platoon_routes(net, max(most, 2), args.min_route, args.seed)
    scenarios: dict[int, Path] = {}
    for c in cases:
        k = c // MEMBERS or len(routes)  # 0: the --no-platoons runs use the largest case
        path = work / f"bench_{c}.yaml"
        data = scenario(f"bench_cosim_{c}", net, routes_file, routes[:k], args, end_for[c])
        path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
        scenarios[c] = path
        done = subprocess.run(cli("validate", str(path)), capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"validate failed: {done.stderr.strip() or done.stdout.strip()}")
        print(f"  {done.stdout.strip()}", flush=True)
    print(f"background: {background} vehicles in {routes_file.name}", flush=True)
    # numba compiles the kernels on their first call and caches them next to the source:
    # a short untimed co-simulation first, so that no timed run pays for compiling
    results = work / "results"
    largest = max(cases)
    if largest:
        warm_end = args.warmup + args.stagger + 10.0
        out_warm = results / "compile_warmup"
        shutil.rmtree(out_warm, ignore_errors=True)
        print(f"compiling the kernels: {largest} platoon vehicles to {warm_end:g} s", flush=True)
        done = subprocess.run(
            cli("run", str(scenarios[largest]), "--out", str(out_warm), "--quiet",
                "--end", repr(warm_end)),
            capture_output=True, text=True,
        )  # fmt: skip
        if done.returncode != 0:
            raise SystemExit(f"warm-up run failed: {done.stderr.strip() or done.stdout.strip()}")

    alone: dict[float, Run] = {}
    bare: dict[float, Run] = {}
    cosim: dict[int, Run] = {}
    skipped: list[int] = []
    # per end time: both baselines and every case with that end, in rounds (a slow
    # spell of the shared host then falls on all of them alike)
    for end in dict.fromkeys(end_for[c] for c in cases):
        group = [c for c in cases if end_for[c] == end and c]
        spent_min = (time.perf_counter() - started) / 60.0
        if args.budget_min is not None and spent_min > args.budget_min and alone:
            skipped = [c for c in cases if end_for[c] not in alone and c]
            print(f"time budget spent ({spent_min:.0f} min): not measured: {skipped}")
            break
        out_alone, out_bare = results / f"sumo_alone_{end:g}", results / f"no_platoons_{end:g}"
        first = next(c for c in cases if end_for[c] == end)  # as the single runs had it
        bare_scenario = str(scenarios[first])
        jobs = [
            Job("SUMO alone", end, out_alone,
                partial(sumo_alone_command, net, routes_file, out_alone, args.seed, end)),
            Job("no platoons", end, out_bare,
                partial(cli, "run", bare_scenario, "--out", str(out_bare), "--quiet",
                        "--no-platoons", "--end", repr(end))),
        ]  # fmt: skip
        for c in group:
            out = results / f"cosim_{c}"
            jobs.append(Job(f"co-sim {c} platoon vehicles", end, out,
                            partial(cli, "run", str(scenarios[c]), "--out", str(out), "--quiet",
                                    "--end", repr(end))))  # fmt: skip
        runs = interleaved(jobs, args.repeat)
        alone[end], bare[end] = runs[0], runs[1]
        cosim.update(zip(group, runs[2:], strict=True))

    stage_lines = []
    if args.timings:
        firsts = {end_for[c]: scenarios[c] for c in reversed(cases) if end_for[c] in alone}

        def sumo_alone(out: Path, end: float) -> list[str]:
            return sumo_alone_command(net, routes_file, out, args.seed, end)

        stage_lines = stage_timings(cosim, scenarios, results)
        stage_lines += baselines_side_by_side(firsts, sumo_alone, results)
    elapsed_min = (time.perf_counter() - started) / 60.0
    lines = [
        f"### {args.label}",
        "",
        f"Command: `{shlex.join([sys.executable, tool, *argv])}`  ",
        f"Date: {dt.date.today().isoformat()}; code: commit {commit} ({where})  ",
        # the interpreter's own file: its build moves the loop's cost (performance.md, session 39)
        f"Machine: {machine()}; Python {platform.python_version()} "
        f"({Path(sys.executable).resolve()}); {sumo_version()}  ",
        f"Background: {background} vehicles in the route file (seed {args.seed}; warm-up "
        f"{args.warmup:g} s at one every {args.warmup_period:g} s, then one every "
        f"{args.period:g} s; trips >= {args.min_trip:g} m); step {STEP_S:g} s; "
        f"CPU = minimum of {args.repeat} run(s), in rounds over the cases and their "
        f"baselines; bench took {elapsed_min:.0f} min",
        "",
        *table(cases, skipped, alone, bare, cosim, end_for),
        "",
        "Wall time of each run [s]: "
        + "; ".join(
            [f"SUMO alone ({e:g} s) {r.wall_s:.0f}" for e, r in sorted(alone.items())]
            + [f"no platoons ({e:g} s) {r.wall_s:.0f}" for e, r in sorted(bare.items())]
            + [f"{c} platoon vehicles ({r.end_s:g} s) {r.wall_s:.0f}" for c, r in cosim.items()]
        )
        + ".  ",
        "SUMO vehicles in the network, SUMO alone (mean / max): "
        + "; ".join(
            f"{e:g} s: {fmt(r.sumo_mean, 0)} / {r.sumo_max}" for e, r in sorted(alone.items())
        )
        + ".",
    ]
    lines += stage_lines
    not_inserted = {c: r.summary.get("platoons_not_inserted", []) for c, r in cosim.items()}
    if any(not_inserted.values()):
        lines.append(
            "Platoons never inserted: "
            + "; ".join(f"{c}: {', '.join(v)}" for c, v in not_inserted.items() if v)
            + "."
        )
    text = "\n".join(lines) + "\n"
    print()
    print(text)
    if not args.no_doc:
        update_doc(doc, args.label, text)
        print(f"written to {doc} (block bench_cosim:{args.label})")
    if not args.keep:
        shutil.rmtree(results, ignore_errors=True)
        if owned:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
