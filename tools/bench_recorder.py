"""Recorder memory on a long, busy run: peak RSS at 15, 30, 45 and 60 simulated minutes.

Builds a 10 x 10 signalised grid (netgenerate, 250 m blocks) in a temporary folder, fills
it with SUMO random trips (2,000+ vehicles in the network at the peak) and sends a
three-car laser platoon across it every five minutes, then runs one simulated hour with
the normal runner (trajectory recorder, statistics, scan snapshot, SUMO outputs). A
step hook samples the process's resident set size (VmRSS, and the peak VmHWM) and the
recorder's own buffers at every quarter hour. Bounded memory means the figures stop
growing once the network is full, while the trajectory file keeps growing.

Usage::

    python tools/bench_recorder.py                 # one hour, writes tools/bench_recorder.md
    python tools/bench_recorder.py --end 900       # a quick look (15 min)
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import sumo
import yaml

from platoon_sumo.runner import load_plan, run

GRID_N, GRID_M = 10, 250.0


def status_kb(field: str) -> int:
    """A field of /proc/self/status in kB (VmRSS: current, VmHWM: peak resident)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return 0


class MemoryProbe:
    """Samples RSS and the recorder's buffers every `every_s` simulated seconds."""

    def __init__(self, every_s: float, table: Path | None = None):
        self.table = table
        self.every_s = every_s
        self.samples: list[dict[str, Any]] = []
        self._next = every_s
        self._start = 0.0

    def on_start(self, run: Any) -> None:
        self._start = time.perf_counter()

    def on_end(self, outcome: Any) -> None:
        pass

    def on_step(self, record: Any) -> None:
        if record.time_s + 1e-9 < self._next:
            return
        self._next += self.every_s
        self.samples.append({
            "time_min": record.time_s / 60.0,
            "vehicles": record.sumo_vehicles,
            "platoon": len(record.vehicles),
            "rss_mb": status_kb("VmRSS") / 1024.0,
            "peak_rss_mb": status_kb("VmHWM") / 1024.0,
            "rows_written": _lines(self.table) - 1 if self.table else 0,
            "wall_s": time.perf_counter() - self._start,
        })  # fmt: skip
        s = self.samples[-1]
        print(f"t = {s['time_min']:5.1f} min  {s['vehicles']:5d} vehicles  "
              f"RSS {s['rss_mb']:7.1f} MB  peak {s['peak_rss_mb']:7.1f} MB  "
              f"rows {s['rows_written']}", flush=True)  # fmt: skip


def _lines(path: Path) -> int:
    """Lines in a file (rows written so far, header included)."""
    with path.open("rb") as f:
        return sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 20), b""))


def build_grid(folder: Path) -> Path:
    net = folder / "grid.net.xml"
    subprocess.run([
        os.path.join(sumo.SUMO_HOME, "bin", "netgenerate"), "--grid",
        "--grid.number", str(GRID_N), "--grid.length", str(GRID_M),
        "--default.lanenumber", "2", "--tls.guess", "true", "--no-turnarounds",
        "--output-file", str(net),
    ], check=True, capture_output=True)  # fmt: skip
    return net


def scenario(net: Path, end_s: float, period_s: float) -> dict[str, Any]:
    last = chr(ord("A") + GRID_N - 1)
    platoons = [
        {
            "id": f"p{k}",
            "route": {"from_edge": "A0B0", "to_edge": f"{last}{GRID_N - 2}{last}{GRID_N - 1}"},
            "depart_s": 60.0 + 300.0 * k,
            "members": 3,
            "spacing_m": 8.0,
            "vehicle": {"model": "bicycle", "length_m": 4.5, "width_m": 1.8, "wheelbase_m": 2.7},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 11.0}},
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"}},
        }
        for k in range(int(end_s // 300))
    ]
    return {
        "name": "bench_recorder",
        "simulation": {"step_s": 0.1, "end_s": end_s, "seed": 7},
        "network": {"net_file": str(net)},
        "traffic": {"random_trips": {"period_s": period_s, "min_distance_m": 1000}},
        "platoons": platoons,
        "outputs": {"tripinfo": True},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--end", type=float, default=3600.0, help="simulated seconds")
    parser.add_argument("--period", type=float, default=0.4, help="random trip period [s]")
    parser.add_argument("--out", default=str(Path(__file__).with_name("bench_recorder.md")))
    args = parser.parse_args(argv)
    probe = MemoryProbe(args.end / 4)
    with tempfile.TemporaryDirectory(prefix="bench_recorder_") as tmp:
        folder = Path(tmp)
        probe.table = folder / "results" / "trajectories.csv"
        net = build_grid(folder)
        path = folder / "bench.yaml"
        path.write_text(yaml.safe_dump(scenario(net, args.end, args.period), sort_keys=False))
        result = run(load_plan(path), out_dir=folder / "results", hooks=[probe])
        traj_mb = (folder / "results" / "trajectories.csv").stat().st_size / 2**20
    s = result.summary
    lines = [
        f"Command: `python tools/bench_recorder.py --end {args.end:g} --period {args.period:g}`  ",
        f"Machine: {platform.machine()}, {os.cpu_count()} cores; Python "
        f"{platform.python_version()}; {s['versions']['sumo']}  ",
        f"Run: {s['simulated_s']:.0f} s simulated in {s['wall_clock_s']:.0f} s; "
        f"{s['all_vehicles']['departed']} vehicles departed, "
        f"{s['platoon_vehicles']['departed']} of them platoon vehicles; "
        f"trajectories.csv {traj_mb:.1f} MB",
        "",
        "| simulated time [min] | vehicles in network | platoon vehicles | RSS [MB] | peak RSS "
        "[MB] | rows on disk |",
        "|---|---|---|---|---|---|",
    ]
    for x in probe.samples:
        lines.append(
            f"| {x['time_min']:.0f} | {x['vehicles']} | {x['platoon']} | {x['rss_mb']:.0f} | "
            f"{x['peak_rss_mb']:.0f} | {x['rows_written']:,} |"
        )
    text = "\n".join(lines) + "\n"
    Path(args.out).write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
