"""Issue 14 acceptance on a real Dask cluster: a scheduler and two workers started as
separate processes on the loopback address, as a user starts them with `dask scheduler`
and `dask worker`."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.study import run_study
from tests.study.conftest import write_study

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out

DASK = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
WORKER = [sys.executable, "-m", "distributed.cli.dask_worker"]


class Cluster:
    def __init__(self, folder: Path) -> None:
        self.file = folder / "scheduler.json"
        self.log = (folder / "cluster.log").open("w")
        self.scheduler = subprocess.Popen(
            [*DASK, "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
             "--scheduler-file", str(self.file)],
            stdout=self.log, stderr=subprocess.STDOUT,
        )  # fmt: skip
        self.workers = [self._worker(folder) for _ in range(2)]
        self.address = self._wait_for_workers(2)

    def _worker(self, folder: Path) -> subprocess.Popen[bytes]:
        while not self.file.exists():
            time.sleep(0.1)
        return subprocess.Popen(
            [*WORKER, "--scheduler-file", str(self.file), "--nthreads", "1", "--no-nanny",
             "--no-dashboard", "--local-directory", str(folder)],
            stdout=self.log, stderr=subprocess.STDOUT,
        )  # fmt: skip

    def _wait_for_workers(self, n: int) -> str:
        from dask.distributed import Client

        address = json.loads(self.file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        with Client(address, timeout="30s") as client:
            client.wait_for_workers(n, timeout=60)
        return address

    def close(self) -> None:
        for proc in [*self.workers, self.scheduler]:
            if proc.poll() is None:
                proc.terminate()
        for proc in [*self.workers, self.scheduler]:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
        self.log.close()


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[Cluster]:
    c = Cluster(tmp_path)
    try:
        yield c
    finally:
        c.close()


def _comparable(table: pd.DataFrame) -> pd.DataFrame:
    return table.drop(columns=["wall_s"]).reset_index(drop=True)


def test_a_study_on_a_running_cluster_gives_the_local_table(cluster, tmp_path):
    study = write_study(tmp_path / "s")
    remote = run_study(study, tmp_path / "remote", scheduler=cluster.address)
    local = run_study(study, tmp_path / "local", workers=2)
    assert (remote.table.status == "complete").all()
    pd.testing.assert_frame_equal(_comparable(remote.table), _comparable(local.table))


def test_a_study_survives_a_worker_killed_in_the_middle(cluster, tmp_path):
    study = write_study(tmp_path / "s")
    out = tmp_path / "out"
    outcomes = out / "outcomes"
    killer_done = []

    def kill_one_worker() -> None:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            if outcomes.is_dir() and any(outcomes.glob("*.json")):
                os.kill(cluster.workers[0].pid, signal.SIGKILL)
                killer_done.append(True)
                return
            time.sleep(0.05)

    import threading

    killer = threading.Thread(target=kill_one_worker, daemon=True)
    killer.start()
    result = run_study(study, out, scheduler=cluster.address)
    killer.join(timeout=5)
    assert killer_done and cluster.workers[0].wait(timeout=10) == -signal.SIGKILL
    table = result.table
    assert len(table) == 8
    # the run the dead worker held was run again on the other one (or, had Dask given up
    # on it, recorded as failed with the reason)
    assert set(table.status) <= {"complete", "failed"}
    assert (table.status == "complete").sum() >= 7
    for row in table[table.status == "failed"].itertuples():
        assert row.reason
