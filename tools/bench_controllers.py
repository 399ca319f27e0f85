"""Benchmark of the controllers: CPU time per ``LaserFollower.step`` and ``RouteFollowing.step``.

Replays the observations recorded from real closed-loop runs
(``tests/control/data/*.obs.xz``, written by ``tests/control/observation_log.py``: the
urban grid platoon, the first DRT city platoon with lane actuation, a robot-scale
follower in the paper world) through the reference follower (the numpy implementation
the kernels replaced, kept as the test oracle ``tests/control/reference_laser_follower.py``)
and through ``platoon_sumo.control.laser_follower.LaserFollower``; prints CPU
microseconds per step for each and the speed-up, the same for ``RoutePath.project``,
and the numba compile time of the kernels on their first call (cold, in a fresh process
with an empty cache; and warm, loading them from that cache). The same observations go
through ``RouteFollowing`` (each log's ``fallback`` parameters, as a leader or the
fallback would see them) and through its previous Python step
(``tests/control/reference_route_following.py``). Writes the tables into
``docs/performance.md`` between ``<!-- bench_controllers -->`` and
``<!-- /bench_controllers -->`` (section "## Controllers"), leaving the rest alone.

The reference and the logs live under ``tests/``: the folder holding the ``tests``
package is put on ``sys.path`` (``--tests-root``, default: this repository).

Usage (from the repository root)::

    python tools/bench_controllers.py                 # measure, print, write the doc
    python tools/bench_controllers.py --no-write      # print only
    python tools/bench_controllers.py --repeats 3 --no-compile
"""

from __future__ import annotations

import argparse
import datetime
import importlib
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numba
import numpy as np

REPO = Path(__file__).resolve().parents[1]
BEGIN, END = "<!-- bench_controllers -->", "<!-- /bench_controllers -->"
SECTION = "## Controllers"
CASES = {
    "urban_platoon": "urban grid, cars, UTM-30LX (1,081 rays), planar actuation",
    "city_platoons": "DRT city, cars, UTM-30LX, lane actuation, on_lost route_following",
    "robot_world": "paper world, robots (docstring's parameters), 720 rays, walls",
}


def replay_us(cls: type, logs: Sequence[Any], repeats: int, timer: Callable[[], float]) -> float:
    """CPU microseconds per step: the best of ``repeats`` replays of every follower log."""
    best = np.inf
    steps = sum(len(log.observations) for log in logs)
    for _ in range(repeats):
        total = 0.0
        for log in logs:
            follower = cls(log.params)
            step = follower.step
            t0 = timer()
            for obs in log.observations:
                step(obs)
            total += timer() - t0
        best = min(best, total / steps * 1e6)
    return float(best)


def route_us(cls: type, logs: Sequence[Any], repeats: int) -> float:
    """CPU microseconds per ``step`` of a route follower (``cls(log.params.fallback)``)
    replaying every log: the best of ``repeats``."""
    best = np.inf
    steps = sum(len(log.observations) for log in logs)
    for _ in range(repeats):
        total = 0.0
        for log in logs:
            step = cls(log.params.fallback).step
            t0 = time.process_time()
            for obs in log.observations:
                step(obs)
            total += time.process_time() - t0
        best = min(best, total / steps * 1e6)
    return float(best)


def following_us(cls: type, logs: Sequence[Any], repeats: int) -> float:
    """Microseconds per step over the steps in "following" mode only (each step timed
    with ``perf_counter``; best of ``repeats``): without the lost / fallback steps."""
    best = np.inf
    for _ in range(repeats):
        total, count = 0.0, 0
        for log in logs:
            follower = cls(log.params)
            for obs in log.observations:
                t0 = time.perf_counter()
                follower.step(obs)
                dt = time.perf_counter() - t0
                if follower.mode == "following":
                    total, count = total + dt, count + 1
        best = min(best, total / max(count, 1) * 1e6)
    return float(best)


def project_us(logs: Sequence[Any], reference: Any, repeats: int) -> tuple[float, float, int]:
    """``RoutePath.project`` as the follower calls it (own position, hint = last arc
    length, window 4 lengths), new and reference, CPU microseconds per call."""
    calls = []
    for log in logs:
        s = None
        for obs in log.observations:
            window = 4.0 * obs.length_m
            calls.append((obs.path, obs.x_m, obs.y_m, s, window))
            s = obs.path.project(obs.x_m, obs.y_m, s, window).s_m
    out = []
    for fn in (
        lambda c: c[0].project(c[1], c[2], c[3], c[4]),
        lambda c: reference.project(c[0], c[1], c[2], c[3], c[4]),
    ):
        best = np.inf
        for _ in range(repeats):
            t0 = time.process_time()
            for c in calls:
                fn(c)
            best = min(best, (time.process_time() - t0) / len(calls) * 1e6)
        out.append(float(best))
    return out[0], out[1], len(calls)


_FIRST_CALL = """
import sys, time, dataclasses
sys.path.insert(0, {root!r})
t0 = time.perf_counter()
from platoon_sumo.control.laser_follower import LaserFollower
from tests.control.observation_log import load
t1 = time.perf_counter()
logs = [load(p)[0] for p in {logs!r}]
def run():
    for log in logs:
        # on_lost=route_following and a short trail too: every kernel is called
        for params in (log.params, dataclasses.replace(log.params, on_lost="route_following")):
            follower = LaserFollower(params)
            for obs in log.observations[:40]:
                follower.step(obs)
t2 = time.perf_counter()
run()
t3 = time.perf_counter()
run()
t4 = time.perf_counter()
print(t1 - t0, (t3 - t2) - (t4 - t3))
"""


def first_call_s(root: Path, logs: Sequence[Path]) -> tuple[float, float, float, float]:
    """(import, first-call overhead) seconds in a fresh process, with an empty numba cache
    (compiling every kernel) and then with the cache it left (loading them)."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        code = _FIRST_CALL.format(root=str(root), logs=[str(p) for p in logs])
        out = []
        for _ in range(2):
            res = subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
            )
            imp, first = (float(v) for v in res.stdout.split())
            out += [imp, first]
    return out[0], out[1], out[2], out[3]


def measure(args: argparse.Namespace) -> dict[str, Any]:
    root = args.tests_root.resolve()
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))  # the tests package: the reference and the logs
    observation_log = importlib.import_module("tests.control.observation_log")
    reference = importlib.import_module("tests.control.reference_laser_follower")
    reference_path = importlib.import_module("tests.control.reference_path")
    reference_route = importlib.import_module("tests.control.reference_route_following")
    from platoon_sumo.control.laser_follower import LaserFollower
    from platoon_sumo.control.route_following import RouteFollowing

    paths = sorted(Path(p) for p in args.logs) if args.logs else list(observation_log.logs())
    result: dict[str, Any] = {"cases": []}
    if not args.no_compile:
        result["first_call"] = first_call_s(root, paths)
    all_logs = []
    for path in paths:
        logs = observation_log.load(path)
        all_logs += logs
        replay_us(LaserFollower, logs, 1, time.process_time)  # warm (kernels loaded)
        new_us, ref_us = np.inf, np.inf
        for _ in range(args.repeats):  # interleaved: both see the same machine load
            new_us = min(new_us, replay_us(LaserFollower, logs, 1, time.process_time))
            ref_us = min(
                ref_us, replay_us(reference.ReferenceLaserFollower, logs, 1, time.process_time)
            )
        follow_us = following_us(LaserFollower, logs, args.repeats)
        steps = sum(len(log.observations) for log in logs)
        name = path.name.removesuffix(".obs.xz")
        result["cases"].append((name, len(logs), steps, ref_us, new_us, follow_us))
        print(f"{name}: {steps} steps, reference {ref_us:.0f} us, new {new_us:.1f} us", flush=True)
        route_us(RouteFollowing, logs, 1)  # warm
        rf_new, rf_ref = np.inf, np.inf
        for _ in range(args.repeats):
            rf_new = min(rf_new, route_us(RouteFollowing, logs, 1))
            rf_ref = min(rf_ref, route_us(reference_route.ReferenceRouteFollowing, logs, 1))
        result.setdefault("route", []).append((name, steps, rf_ref, rf_new))
        print(f"{name}: route following, before {rf_ref:.1f} us, new {rf_new:.1f} us", flush=True)
    result["project"] = project_us(all_logs, reference_path, args.repeats)
    return result


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if "model name" in line)
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def render(result: dict[str, Any], command: str) -> str:
    rows = [
        "| Case | Followers, steps | Reference µs/step | New µs/step | Speed-up "
        "| New, following steps only |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for name, n, steps, ref_us, new_us, follow_us in result["cases"]:
        label = f"`{name}`: {CASES.get(name, '')}".rstrip(": ")
        rows.append(
            f"| {label} | {n}, {steps:,} | {ref_us:,.0f} | **{new_us:.1f}** "
            f"| {ref_us / new_us:,.0f}x | {follow_us:.1f} |"
        )
    new_p, ref_p, calls = result["project"]
    rows.append(
        f"| `RoutePath.project` per call (window of 4 lengths around the last arc length) "
        f"| {calls:,} calls | {ref_p:.1f} | **{new_p:.2f}** | {ref_p / new_p:,.0f}x | |"
    )
    route_rows = [
        "| Case | Steps | Reference µs/step | New µs/step | Speed-up |",
        "|---|---|---:|---:|---:|",
    ]
    for name, steps, ref_us, new_us in result.get("route", []):
        route_rows.append(
            f"| `{name}` | {steps:,} | {ref_us:.1f} | **{new_us:.1f}** | {ref_us / new_us:.1f}x |"
        )
    lines = [
        f"Command: `{command}`  ",
        f"Machine: {cpu_model()}, {os.cpu_count()} cores; "
        f"Python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}  ",
        f"Date: {datetime.date.today().isoformat()}; CPU time (process_time), best of "
        "repeated replays, no profiler. The last column times each step in "
        '"following" mode alone (wall clock): without the steps on the route-following '
        "fallback (its `RouteFollowing.step`) or stopping.",
        "",
        "Laser follower (`LaserFollower.step`) against the numpy follower it replaced:",
        "",
        *rows,
        "",
        "Route following (`RouteFollowing.step`, each log's `fallback` parameters, the "
        "observations as a leader would get them) against the test oracle, its previous "
        "Python step with the path look-ups as free functions "
        "(`tests/control/reference_route_following.py`, slower than the step it copies):",
        "",
        *route_rows,
    ]
    if "first_call" in result:
        imp_cold, cold, imp_warm, warm = result["first_call"]
        lines += [
            "",
            "numba kernels on their first call (fresh process, every kernel the follower "
            "uses): "
            f"**{cold:.1f} s** compiling them with an empty cache, **{warm:.2f} s** loading "
            f"them from the cache (`cache=True`, `__pycache__` next to the kernels) later; "
            f"importing the follower takes {imp_cold:.2f} s / {imp_warm:.2f} s.",
        ]
    return "\n".join(lines) + "\n"


_INTRO = f"""{SECTION}

Measured by `tools/bench_controllers.py`; the table between the markers is rewritten by
each run of it.

{BEGIN}
{END}
"""


def write_section(path: Path, body: str) -> None:
    """Replace the text between the markers (adding the section if it is missing); the
    file is read right before it is written, and nothing else in it changes."""
    text = path.read_text() if path.exists() else "# Performance\n"
    if BEGIN not in text or END not in text:
        text = text.rstrip("\n") + "\n\n" + _INTRO
    start = text.index(BEGIN) + len(BEGIN)
    end = text.index(END, start)
    path.write_text(text[:start] + "\n" + body + text[end:])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--tests-root",
        type=Path,
        default=REPO,
        help="folder holding the tests package (reference follower, recorded logs)",
    )
    parser.add_argument("--logs", nargs="*", help="observation logs (default: all recorded)")
    parser.add_argument("--repeats", type=int, default=5, help="replays per follower")
    parser.add_argument(
        "--out",
        type=Path,
        default=REPO / "docs" / "performance.md",
        help="markdown file whose bench_controllers block is rewritten",
    )
    parser.add_argument("--no-write", action="store_true", help="print the table only")
    parser.add_argument("--no-compile", action="store_true", help="skip the compile timing")
    args = parser.parse_args(argv)
    command = "python tools/bench_controllers.py" + (
        f" --repeats {args.repeats}" if args.repeats != 5 else ""
    )
    body = render(measure(args), command)
    print(body)
    if not args.no_write:
        write_section(args.out, body)
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
