"""The live view (`platoon-sumo run --gui`): sumo-gui under a virtual display shows the
run and changes nothing in it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from platoon_sumo.live_view import LiveViewOptions
from platoon_sumo.loop.context import RunContext, RunOutcome, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out

SCENARIO = REPO / "scenarios" / "urban_platoon.yaml"
CLI = [sys.executable, "-m", "platoon_sumo.cli"]  # as the other command-line tests run it
END_S = 55.0  # the platoon departs at 40 s: a few seconds of five cars and their scans


@pytest.fixture(scope="module")
def display() -> Iterator[str]:
    """A display for sumo-gui: the session's, else a virtual one (Xvfb) for this module."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("no display and no Xvfb to make one: apt-get install xvfb (.ci/run does)")
    number = 90 + os.getpid() % 500
    server = subprocess.Popen(
        [xvfb, f":{number}", "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    socket = Path(f"/tmp/.X11-unix/X{number}")
    deadline = time.monotonic() + 20
    while not socket.exists() and server.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    if not socket.exists():
        server.kill()
        pytest.fail(f"Xvfb did not start on :{number}")
    os.environ["DISPLAY"] = f":{number}"
    try:
        yield f":{number}"
    finally:
        del os.environ["DISPLAY"]
        server.terminate()
        server.wait(timeout=10)


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=600)


def test_gui_run_has_the_libsumo_runs_results(display: str, tmp_path: Path) -> None:
    common = ("run", str(SCENARIO), "--end", str(END_S), "--quiet")
    plain = _cli(*common, "--out", str(tmp_path / "plain"))
    gui = _cli(*common, "--out", str(tmp_path / "gui"), "--gui", "--gui-delay", "0")
    assert plain.returncode == 0, plain.stderr
    assert gui.returncode == 0, gui.stderr
    for name in ("trajectories.csv", "events.csv", "vehicles.csv", "platoons.csv"):
        assert (tmp_path / "gui" / name).read_bytes() == (tmp_path / "plain" / name).read_bytes()
    rows = (tmp_path / "gui" / "trajectories.csv").read_text().count("\n") - 1
    assert rows > 5 * 10 * (END_S - 45)  # five cars, most of their first 15 s


class Screenshot:
    """Asks sumo-gui for a picture of the view at a time (written at the next step)."""

    def __init__(self, at_s: float, path: Path):
        self.at_s, self.path, self.taken = at_s, path, False

    def on_start(self, run: RunContext) -> None:
        pass

    def on_step(self, record: StepRecord) -> None:
        if not self.taken and record.time_s >= self.at_s:
            import traci

            traci.gui.screenshot("View #0", str(self.path))
            self.taken = True

    def on_end(self, outcome: RunOutcome) -> None:
        pass


def _view(tmp_path: Path, rays: str) -> np.ndarray:
    """The live view 3 s before the end, following cars.1, as RGB pixels."""
    shot = tmp_path / f"view_{rays}.png"
    plan = load_plan(SCENARIO, end_s=END_S)
    live = LiveViewOptions(vehicle="cars.1", rays=rays, zoom=800.0)  # type: ignore[arg-type]
    hooks = [Screenshot(END_S - 3.0, shot)]
    run(plan, out_dir=tmp_path / f"run_{rays}", hooks=hooks, live_view=live)
    return np.asarray(Image.open(shot).convert("RGB"), dtype=int)


def test_live_view_draws_the_followed_vehicles_rays(display: str, tmp_path: Path) -> None:
    with_rays, without = _view(tmp_path, "chosen"), _view(tmp_path, "none")
    assert with_rays.shape == without.shape
    changed = np.any(with_rays != without, axis=2)
    assert changed.sum() > 500  # the fan of cars.1's returns, its view and its hits
    r, g, b = with_rays[..., 0], with_rays[..., 1], with_rays[..., 2]
    green = (g > r + 60) & (g > b + 60)
    assert (changed & green).sum() > 0.5 * changed.sum()  # ... drawn in the rays' green


def test_closing_sumo_gui_ends_the_run_as_failed_with_one_line(display: str, tmp_path: Path):
    """The user closes the window mid-run: one error line (no traceback, not an
    "internal error"), exit 1, and the folder says the run failed and keeps its table."""
    out = tmp_path / "closed"
    args = ["run", str(SCENARIO), "--out", str(out), "--quiet", "--gui", "--gui-delay", "100"]
    cli = subprocess.Popen([*CLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pattern = f"sumo-gui.*{out}"
    deadline = time.monotonic() + 60
    while subprocess.run(["pgrep", "-f", pattern], capture_output=True).returncode != 0:
        assert cli.poll() is None and time.monotonic() < deadline, "sumo-gui did not start"
        time.sleep(0.2)
    time.sleep(4.0)  # a few dozen steps with the 100 ms delay
    subprocess.run(["pkill", "-f", pattern], check=True)
    _, stderr = cli.communicate(timeout=60)
    assert cli.returncode == 1
    lines = [line for line in stderr.splitlines() if line.startswith("error:")]
    assert lines == [lines[0]] and "sumo-gui closed the connection" in lines[0]
    assert "Traceback" not in stderr and "internal error" not in stderr
    assert (out / "FAILED.txt").read_text().startswith("failed: SumoError: sumo-gui closed")
    assert not (out / "summary.json").exists()
    assert (out / "trajectories.csv").stat().st_size > 0
