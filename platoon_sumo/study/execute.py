"""Running a study's runs on Dask: a local cluster of worker processes (one simulation
per process at a time: libsumo holds one simulation per process) or an existing
scheduler. Each run writes its own results folder; its outcome is recorded by the
coordinating process as it arrives, so a finished run is skipped when the study is run
again, and a run lost with its worker is run again by Dask."""

from __future__ import annotations

import math
import sys
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from platoon_sumo.results import COMPLETE, FAILED


@dataclass(frozen=True)
class Outcome:
    """How a run ended: status, the reason of a failure, its wall time [s]."""

    status: str
    reason: str = ""
    wall_s: float = math.nan


def run_one(scenario: str, out_dir: str) -> dict[str, Any]:
    """Run one scenario into `out_dir` (on a worker); never raises for the run's own
    failure: it is returned, with the error's last line, as the run's outcome."""
    from platoon_sumo.runner import load_plan, run

    began = time.perf_counter()
    try:
        # force: a folder left by a run of ours that never finished (a lost worker)
        run(load_plan(scenario), out_dir, force=True)
    except Exception as exc:  # the run's failure is data, not the study's
        last = traceback.format_exception_only(exc)[-1].strip()
        return {"status": FAILED, "reason": last, "wall_s": time.perf_counter() - began}
    return {"status": COMPLETE, "reason": "", "wall_s": time.perf_counter() - began}


def execute(
    jobs: Mapping[str, tuple[Path, Path]],
    record: Callable[[str, Outcome], None],
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Callable[[int, int, int, int], None] | None = None,
) -> dict[str, Outcome]:
    """Run `jobs` ({run id: (scenario file, results folder)}) on Dask; `record(run id,
    outcome)` as each finishes, and return them all. `scheduler`: the address of a
    running scheduler; else a local cluster of `workers` processes (default: the cores).
    `progress(done, failed, running, total)` is called as runs finish."""
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers or None, threads_per_worker=1, processes=True,
            dashboard_address=":0", silence_logs=40,  # any free port: never a clash
        )  # fmt: skip
    client = Client(cluster if cluster is not None else scheduler, timeout="30s")
    outcomes: dict[str, Outcome] = {}
    try:
        futures = {
            client.submit(run_one, str(scenario), str(out), key=f"run-{rid}", pure=False): rid
            for rid, (scenario, out) in jobs.items()
        }
        total, failed = len(futures), 0
        if progress:
            progress(0, 0, min(total, _slots(client)), total)
        for future in as_completed(futures):
            rid = futures[future]
            try:
                result = future.result()
                outcome = Outcome(result["status"], result["reason"], result["wall_s"])
            except Exception as exc:  # the worker died with it more often than allowed
                outcome = Outcome(FAILED, f"{type(exc).__name__}: {exc}".strip())
            record(rid, outcome)
            outcomes[rid] = outcome
            failed += outcome.status != COMPLETE
            if progress:
                left = total - len(outcomes)
                progress(len(outcomes), failed, min(left, _slots(client)), total)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return outcomes


def _slots(client: Any) -> int:
    """Runs that can go at once: the workers' threads."""
    try:
        return max(sum(w["nthreads"] for w in client.scheduler_info()["workers"].values()), 1)
    except Exception:
        return 1


class ProgressLine:
    """`runs 12/40 done, 1 failed, 2 running, about 3 min left` on one line (stderr)."""

    def __init__(self, stream: TextIO = sys.stderr) -> None:
        self.stream = stream
        self.began = time.perf_counter()
        self.tty = stream.isatty()

    def __call__(self, done: int, failed: int, running: int, total: int) -> None:
        elapsed = time.perf_counter() - self.began
        left = ""
        if done:
            seconds = elapsed / done * (total - done)
            left = f", about {seconds / 60:.0f} min left" if seconds >= 90 else ""
            left = left or f", {seconds:.0f} s left"
        line = f"runs {done}/{total} done, {failed} failed, {running} running{left}"
        self.stream.write(("\r" + line + "\x1b[K") if self.tty else line + "\n")
        if self.tty and done == total:
            self.stream.write("\n")
        self.stream.flush()
