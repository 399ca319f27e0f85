"""The garbage collector's passes in one `platoon-sumo run`: how many, of which generation,
and their CPU, before the loop's steps, during them and after.

A profiler charges a collection to whatever line happened to allocate, so the
collector's cost does not show there; this times each pass with `gc.callbacks` and the
thread's CPU clock. Used for the collector table of docs/performance.md (session 37);
give `PYTHONPATH` a worktree of another commit to time that code::

    python tools/gc_passes.py scenarios/city_platoons.yaml --end 200
"""

from __future__ import annotations

import argparse
import collections
import gc
import sys
import tempfile
import time
from typing import Any

PHASES = ("before the steps", "during the steps", "after them")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", help="scenario file")
    parser.add_argument("--end", type=float, help="simulated seconds [s]")
    args = parser.parse_args()

    phase = [PHASES[0]]
    started = [0.0]
    passes: collections.Counter[tuple[str, int]] = collections.Counter()
    cpu_s: collections.Counter[tuple[str, int]] = collections.Counter()

    def timed(event: str, info: dict[str, Any]) -> None:
        if event == "start":
            started[0] = time.thread_time()
            return
        key = (phase[0], info["generation"])
        passes[key] += 1
        cpu_s[key] += time.thread_time() - started[0]

    gc.callbacks.append(timed)  # before the imports: their passes count too
    start = time.process_time()
    from platoon_sumo import cosim
    from platoon_sumo.cli import main as cli_main

    run = cosim.CoSimulation.run

    def phased_run(self: cosim.CoSimulation) -> Any:
        phase[0] = PHASES[1]
        try:
            return run(self)
        finally:
            phase[0] = PHASES[2]

    cosim.CoSimulation.run = phased_run  # type: ignore[method-assign]
    with tempfile.TemporaryDirectory() as out:
        argv = ["run", args.scenario, "--quiet", "--out", out]
        code = cli_main([*argv, *(["--end", str(args.end)] if args.end else [])])
    total_s = time.process_time() - start
    gc.callbacks.remove(timed)
    print(f"{args.scenario}: the run's CPU {total_s:.2f} s (exit code {code})")
    for name in PHASES:
        parts = [
            f"generation {g}: {passes[name, g]} passes, {1e3 * cpu_s[name, g]:.0f} ms"
            for g in range(3)
            if passes[name, g]
        ]
        spent = sum(cpu_s[name, g] for g in range(3))
        print(f"  {name}: {1e3 * spent:.0f} ms" + (f" ({'; '.join(parts)})" if parts else ""))
    return code


if __name__ == "__main__":
    sys.exit(main())
