"""Ctrl-C and SIGTERM end a run the same way: what it wrote is kept and marked
interrupted, the exit code says which signal, and no child process outlives it.

Each case starts `platoon-sumo run` as a real process and signals it mid-run.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
import yaml

from platoon_sumo.results import MANIFEST
from tests.helpers import REPO, URBAN_GRID_NET

STRAIGHT = REPO / "networks" / "straight" / "straight.net.xml"


def long_run() -> dict[str, Any]:
    return {
        "name": "long",
        "simulation": {"step_s": 0.1, "end_s": 3000.0, "seed": 1},
        "network": {"net_file": str(STRAIGHT)},
        "platoons": [
            {
                "id": "p",
                "route": {"edges": ["WE"]},
                "members": 2,
                "depart_pos_m": 40.0,
                "actuation": "lane",
                "leader": {"type": "route_following", "params": {"cruise_speed_mps": 0.5}},
                "follower": {"type": "route_following", "params": {"cruise_speed_mps": 0.5}},
            }
        ],
    }


def start(tmp_path: Path, data: dict[str, Any]) -> tuple[subprocess.Popen[str], Path]:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "platoon_sumo.cli", "run", str(path), "--out", str(out)]
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path
    )
    return child, out


def rows_written(path: Path) -> int:
    """Data rows in a CSV output so far (0 before it exists)."""
    if not path.is_file():
        return 0
    with path.open(encoding="utf-8") as f:
        return max(sum(1 for _ in f) - 1, 0)


def wait_for(condition: Any, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "timed out waiting for the run"
        time.sleep(0.05)


@pytest.mark.parametrize(("signum", "code", "name"), [
    (signal.SIGTERM, 143, "SIGTERM"), (signal.SIGINT, 130, "Ctrl-C"),
])  # fmt: skip
@pytest.mark.slow
def test_a_signal_mid_run_keeps_the_rows_and_marks_the_run_interrupted(
    tmp_path, signum, code, name
):
    child, out = start(tmp_path, long_run())
    # mid-run: the scene file's first chunk written (60 simulated seconds), the
    # trajectory rows still in memory (a chunk is 20,000 rows). Neither wall time nor the
    # run's CPU time says that: on a busy machine 1.5 s of wall time once left it no step
    # done, and 1.5 s of its CPU went to compiling the kernels on a fresh checkout
    wait_for(lambda: rows_written(out / "scene.csv") > 0, timeout_s=300.0)
    child.send_signal(signum)
    _, err = child.communicate(timeout=60)
    assert child.returncode == code, err
    assert err.strip().splitlines()[-1] == f"interrupted ({name})" and "Traceback" not in err, err
    failed = (out / "FAILED.txt").read_text()
    assert failed.startswith("interrupted: "), failed
    assert not (out / "summary.json").exists()
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["status"] == "interrupted"
    rows = pd.read_csv(out / "trajectories.csv")
    assert len(rows) > 20 and set(rows["vehicle_id"]) == {"p.0", "p.1"}, (len(rows), failed)
    # every step up to the signal: the end hook wrote the rows still in memory
    scene_s = pd.read_csv(out / "scene.csv")["time_s"].max()
    assert rows["time_s"].max() >= scene_s, (rows["time_s"].max(), scene_s, failed)
    assert "trajectories.csv" in manifest["files"]  # kept, and listed as ours


def _processes_naming(text: str) -> list[str]:
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if text in cmdline:
            found.append(cmdline)
    return found


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to list processes")
def test_sigterm_while_the_demand_is_made_ends_sumos_tools_too(tmp_path):
    data = {
        "name": "demand",
        "simulation": {"step_s": 0.1, "end_s": 3600.0, "seed": 1},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "traffic": {"random_trips": {"period_s": 0.02}},  # randomTrips + duarouter: seconds
        "platoons": [],
    }
    child, out = start(tmp_path, data)
    inputs = str(out / "inputs")
    # signalled once randomTrips.py has started its own child, duarouter
    wait_for(lambda: any("duarouter" in c for c in _processes_naming(inputs)))
    child.send_signal(signal.SIGTERM)
    _, err = child.communicate(timeout=60)
    assert child.returncode == 143, err
    time.sleep(0.2)
    assert _processes_naming(inputs) == []  # randomTrips.py and duarouter
    assert json.loads((out / MANIFEST).read_text())["status"] == "interrupted"
