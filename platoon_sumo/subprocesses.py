"""Child processes (SUMO's Python tools, netconvert) that end with the run.

A child and everything it starts (randomTrips.py runs duarouter) get their own process
group, so Ctrl-C, SIGTERM or an error in this process ends the whole group instead of
leaving it running as an orphan.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
from collections.abc import Sequence
from pathlib import Path


def run_tool(
    cmd: Sequence[str], env: dict[str, str] | None = None, cwd: str | Path | None = None
) -> subprocess.CompletedProcess[str]:
    """Run `cmd` to its end with its output captured (as text); if this process is
    interrupted or fails meanwhile, kill the child's process group first."""
    with subprocess.Popen(
        list(cmd), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        cwd=cwd, start_new_session=True,
    ) as child:  # fmt: skip
        try:
            stdout, stderr = child.communicate()
        except BaseException:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(child.pid, signal.SIGKILL)
            child.wait()
            raise
    return subprocess.CompletedProcess(child.args, child.returncode, stdout, stderr)
