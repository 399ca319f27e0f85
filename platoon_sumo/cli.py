"""`platoon-sumo`: run and validate scenarios.

Bad input ends with one line on stderr naming the file and key, and exit code 2;
a simulation failure ends with one line and exit code 1; never a traceback.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, TextIO

import numpy as np

import platoon_sumo
from platoon_sumo.errors import PlatoonSumoError, ScenarioError, Terminated, UsageError
from platoon_sumo.results import FolderError

if TYPE_CHECKING:
    from platoon_sumo.live_view import LiveViewOptions
    from platoon_sumo.loop.context import RunContext, RunOutcome, StepRecord
    from platoon_sumo.scenario import RunPlan
    from platoon_sumo.sensors.laser import LaserScan

DEFAULT_SCENARIO = Path("scenarios") / "urban_platoon.yaml"
#: Set to show the traceback of an internal error instead of one line.
TRACEBACK_ENV = "PLATOON_SUMO_TRACEBACK"


def default_scenario() -> Path:
    """The default scenario: in the working directory, else in the source checkout."""
    for root in (Path.cwd(), Path(platoon_sumo.__file__).resolve().parent.parent):
        if (root / DEFAULT_SCENARIO).is_file():
            return root / DEFAULT_SCENARIO
    raise ScenarioError(
        str(DEFAULT_SCENARIO), "", "default scenario not found",
        "run from the platoon-sumo checkout, or name a scenario file",
    )  # fmt: skip


class Progress:
    """One status line: simulated time, real-time factor, vehicles in the network."""

    def __init__(self, stream: TextIO, interval_s: float = 0.5):
        self.stream = stream
        self.interval_s = interval_s
        self.tty = stream.isatty()
        self._start = 0.0
        self._last = 0.0
        self._last_decile = -1
        self._begin_s = self._end_s = 0.0
        self._collisions = 0

    def on_start(self, run: RunContext) -> None:
        self._start = self._last = time.perf_counter()
        self._begin_s, self._end_s = run.begin_s, run.end_s

    def on_step(self, record: StepRecord) -> None:
        from platoon_sumo.events import EventKind

        self._collisions += len(record.of_kind(EventKind.COLLISION, EventKind.WALL_CONTACT))
        now = time.perf_counter()
        begin = self._begin_s
        fraction = (record.time_s - begin) / max(self._end_s - begin, 1e-9)
        decile = int(fraction * 10)
        if self.tty and now - self._last < self.interval_s:
            return
        if not self.tty and decile == self._last_decile:
            return
        self._last, self._last_decile = now, decile
        rtf = (record.time_s - begin) / max(now - self._start, 1e-9)
        line = (
            f"t = {record.time_s:8.1f} / {self._end_s:.0f} s ({fraction:4.0%})  "
            f"{rtf:7.1f}x real time  {record.sumo_vehicles:5d} vehicles  "
            f"{len(record.columns):3d} platoon  {self._collisions} collisions"
        )
        self.stream.write(("\r" + line) if self.tty else line + "\n")
        self.stream.flush()

    def on_end(self, outcome: RunOutcome) -> None:
        if self.tty:
            self.stream.write("\n")


#: Network warnings shown before "... and N more".
SHOWN_WARNINGS = 5


def _network_warnings(plan: RunPlan) -> None:
    """What in the network or the sensing may spoil a run without being an error
    (stderr)."""
    from platoon_sumo.sumo.signals import long_signal_phases

    try:
        found = long_signal_phases([plan.net_file, *plan.additional_files])
    except ValueError as exc:
        raise ScenarioError(str(plan.source.path), "network", str(exc)) from None
    for message in found[:SHOWN_WARNINGS]:
        print(f"warning: {message}", file=sys.stderr)
    if len(found) > SHOWN_WARNINGS:
        print(f"warning: ... and {len(found) - SHOWN_WARNINGS} more long phases", file=sys.stderr)
    from platoon_sumo.sensing_checks import laser_range_warnings, laser_view_warnings

    for message in laser_range_warnings(plan) + laser_view_warnings(plan):
        print(f"warning: {message}", file=sys.stderr)
    invented: dict[str, list[str]] = {}  # message -> platoons whose route meets it
    for platoon in plan.platoons:
        for message in plan.network.invented_on_route(platoon.edges):
            invented.setdefault(message, []).append(platoon.config.id)
    for message, platoons in invented.items():
        names = ", ".join(f"'{p}'" for p in platoons[:3]) + (" ..." if len(platoons) > 3 else "")
        print(
            f"warning: {plan.source.path}: route of platoon {names}: {message}; its geometry "
            "may not match the road (check it in netedit, or route around it)",
            file=sys.stderr,
        )


def _cmd_run(args: argparse.Namespace) -> int:
    from platoon_sumo.digest import run_digest
    from platoon_sumo.runner import load_plan, run

    path = Path(args.scenario) if args.scenario else default_scenario()
    plan = load_plan(path, end_s=args.end, seed=args.seed, without_platoons=args.no_platoons)
    _network_warnings(plan)
    hooks = [] if args.quiet else [Progress(sys.stderr)]
    if hooks and plan.platoons and not _kernels_compiled():
        print(
            "note: the first run after installing compiles the loop's kernels once (about a "
            "minute on 2 cores, the run meanwhile slower); later runs load them",
            file=sys.stderr,
        )
    live_view = _live_view(args, plan)
    result = run(
        plan, out_dir=args.out, hooks=hooks, force=args.force, live_view=live_view,
        timings=args.timings,
    )  # fmt: skip
    s = result.summary
    depart = {p.config.id: p.config.depart_s for p in plan.platoons}
    for pid in s.get("platoons_not_inserted", []):
        why = (
            "it departs after the simulation's end"
            if depart[pid] > plan.scenario.simulation.end_s - plan.scenario.simulation.step_s
            else "its first lane never had room for its first members (try another depart_s, "
            "depart_pos_m or first edge)"
        )
        print(f"warning: platoon '{pid}' was never inserted: {why}", file=sys.stderr)
    if s.get("members_not_inserted"):
        print(
            f"warning: {len(s['members_not_inserted'])} platoon member(s) still waited for "
            "room on their first edge at the end: "
            + ", ".join(s["members_not_inserted"][:SHOWN_WARNINGS]),
            file=sys.stderr,
        )
    for removed in s.get("removed_off_route", []):
        print(f"warning: taken out of the run: {removed['reason']}", file=sys.stderr)
    for jam in s.get("gridlock_events", [])[:3]:
        print(
            f"warning: gridlock: '{jam['vehicle_id']}' at t={jam['time_s']:.0f} s, "
            f"{jam['where']} (summary.json: gridlock_events)",
            file=sys.stderr,
        )
    print(run_digest(s, _as_typed(result.directory), _as_typed(path)))
    if args.timings:
        import pandas as pd

        from platoon_sumo.loop.timing import headline
        from platoon_sumo.runner import TIMINGS_FILE

        timings = result.directory / TIMINGS_FILE
        print(f"{headline(pd.read_csv(timings))} ({timings})")
    return 0


def _kernels_compiled() -> bool:
    """Whether the kernels every platoon run calls are compiled already (an unreadable
    cache counts as compiled: no note rather than a wrong one)."""
    from platoon_sumo.kernels import in_cache
    from platoon_sumo.kernels.route import project_members

    return in_cache(project_members) is not False


def _live_view(args: argparse.Namespace, plan: RunPlan) -> LiveViewOptions | None:
    """The live view asked for on the command line, its vehicle checked against the plan."""
    from platoon_sumo.live_view import LiveViewOptions

    if not args.gui:
        if args.gui_vehicle is not None:
            raise UsageError("--gui-vehicle: only with --gui (the live view in sumo-gui)")
        return None
    members = [m.vehicle_id for p in plan.platoons for m in p.members]
    if args.gui_vehicle is not None and args.gui_vehicle not in members:
        shown = ", ".join(members[:8]) + (" ..." if len(members) > 8 else "")
        raise UsageError(
            f"--gui-vehicle {args.gui_vehicle!r}: no platoon vehicle of that id in "
            f"{plan.source.path} (its vehicles: {shown or 'none'})"
        )
    from platoon_sumo.sumo.backend import gui_display_problem

    if problem := gui_display_problem():
        raise UsageError(problem)
    if not (math.isfinite(args.gui_delay) and args.gui_delay >= 0):
        raise UsageError(f"--gui-delay {args.gui_delay:g}: give a pause of 0 ms or more")
    return LiveViewOptions(args.gui_vehicle, args.gui_rays, delay_ms=args.gui_delay)


def _as_typed(path: Path) -> Path:
    """`path` relative to the working directory when it lies below it (to type again)."""
    try:
        return path.resolve().relative_to(Path.cwd())
    except ValueError:
        return path


class ScanGrabber:
    """Keeps the latest scan of one vehicle with the obstacles of the world it saw, and
    which of them are the scanning car and its predecessor (rows of `rectangles`)."""

    def __init__(self, vehicle_id: str | None):
        self.vehicle_id = vehicle_id
        self.scan: LaserScan | None = None
        self.rectangles: np.ndarray | None = None
        self.segments: np.ndarray | None = None
        self.scanner: tuple[int, str] | None = None
        self.predecessor: tuple[int, str] | None = None

    def on_start(self, run: RunContext) -> None:
        self.segments = run.static_segments

    def on_end(self, outcome: RunOutcome) -> None:
        pass

    def on_step(self, record: StepRecord) -> None:
        seen = record.sensed_world
        # by default a follower's scan: it shows the predecessor it follows
        for v in sorted(record.vehicles, key=lambda v: v.predecessor_id is None):
            wanted = self.vehicle_id is None or v.id == self.vehicle_id
            scan = v.scan
            if wanted and scan is not None and seen is not None and seen.time_s == scan.stamp_s:
                self.scan, self.rectangles = scan, record.sensed_footprints
                self.scanner = _row_of(seen.index, v.id)
                self.predecessor = _row_of(seen.index, v.predecessor_id)
                break


def _row_of(index: dict[str, int], vehicle_id: str | None) -> tuple[int, str] | None:
    """(row, id) of a vehicle among the footprints a scan saw; None if it is not there."""
    if vehicle_id is None or vehicle_id not in index:
        return None
    return index[vehicle_id], vehicle_id


def _scan_path(out: str | None, plan: RunPlan, vehicle_id: str, stamp_s: float) -> Path:
    """Where the scan's PNG goes: `--out` as a file (a name ending in .png), else a new
    file in the folder `--out` names, or in the scenario's results folder."""
    from platoon_sumo.results import add_file
    from platoon_sumo.runner import results_directory

    if out is not None and Path(out).suffix.lower() == ".png" and not Path(out).is_dir():
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        return Path(out)
    safe_id = "".join(c if c.isalnum() or c in "._-" else "_" for c in vehicle_id)
    folder = Path(out) if out is not None else results_directory(plan)
    return add_file(folder, f"laser_scan_{safe_id}_t{stamp_s:g}.png")


def _cmd_scan(args: argparse.Namespace) -> int:
    import tempfile

    from platoon_sumo.runner import load_plan, run
    from platoon_sumo.scenario import load_scenario
    from platoon_sumo.sensors.plot import plot_scan

    sim = load_scenario(args.scenario).scenario.simulation  # the file only: no network yet
    if not (math.isfinite(args.at) and sim.begin_s < args.at <= sim.end_s):
        raise ScenarioError(
            args.scenario, "--at", f"{args.at:g} s is not a time of this run",
            f"give a time after simulation.begin_s = {sim.begin_s:g} s, up to "
            f"simulation.end_s = {sim.end_s:g} s",
        )  # fmt: skip
    plan = load_plan(args.scenario, end_s=args.at)
    grabber = ScanGrabber(args.vehicle)
    with tempfile.TemporaryDirectory() as tmp:
        run(plan, out_dir=tmp, hooks=[grabber])
    scan = grabber.scan
    if scan is None or grabber.scanner is None:
        who = f"vehicle '{args.vehicle}'" if args.vehicle else "any platoon vehicle"
        raise ScenarioError(
            args.scenario, "platoons", f"no laser scan of {who} by t = {args.at} s",
            "give the platoon a sensor, and a time after it departs",
        )  # fmt: skip
    vehicle_id = grabber.scanner[1]
    predecessor = f", predecessor {grabber.predecessor[1]}" if grabber.predecessor else ""
    title = (f"Laser scan of {vehicle_id} at t = {scan.stamp_s:.2f} s{predecessor}\n"
             f"({plan.scenario.name})")  # fmt: skip
    path = _scan_path(args.out, plan, vehicle_id, scan.stamp_s)
    plot_scan(scan, grabber.rectangles, grabber.segments, path, title=title,
              scanner=grabber.scanner, predecessor=grabber.predecessor)  # fmt: skip
    print(f"scan written to {path} ({vehicle_id} at t = {scan.stamp_s:.2f} s)")
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    from platoon_sumo.scenario import load_scenario, prepare

    plan = prepare(load_scenario(args.scenario))
    _network_warnings(plan)
    members = sum(len(p.members) for p in plan.platoons)
    print(
        f"{args.scenario}: OK ({len(plan.platoons)} platoons, {members} vehicles, "
        f"network {plan.net_file.name})"
    )
    return 0


def _warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


def _cmd_report(args: argparse.Namespace) -> int:
    from platoon_sumo.report import write_report

    path = write_report(args.results, args.out, warn=_warn)
    print(f"report written to {path}")
    return 0


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, got {text!r}") from None
    return width, height


def _cmd_animate(args: argparse.Namespace) -> int:
    from platoon_sumo.report.animation import animate, progress_line

    done = animate(
        args.results, args.out, args.vehicle, args.start_s, args.end_s, args.fps, args.size,
        args.window, None if args.quiet else progress_line(), warn=_warn,
    )  # fmt: skip
    print(
        f"animation written to {done.path} ({done.frames} frames, "
        f"{done.frames / max(done.render_s, 1e-9):.1f} frames/s)"
    )
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from platoon_sumo.report import write_comparison

    path = write_comparison(args.results, args.out, warn=_warn)
    print(f"comparison written to {path}")
    return 0


def _cmd_study(args: argparse.Namespace) -> int:
    from platoon_sumo.study import describe, load_study, run_study
    from platoon_sumo.study.execute import ProgressLine

    print(describe(load_study(args.study)), file=sys.stderr)
    result = run_study(
        args.study, args.out, args.workers, args.scheduler, None if args.quiet else ProgressLine()
    )
    table = result.table
    failed = table[table.status != "complete"]
    print(
        f"{len(table)} runs ({len(result.ran)} run now, {len(table) - len(result.ran)} "
        f"finished before), {len(failed)} failed; table: {result.folder / 'study.csv'}"
    )
    for row in failed.itertuples():
        print(f"failed: run {row.run_id}: {row.reason}", file=sys.stderr)
    for message in result.warnings:
        print(f"warning: {message}", file=sys.stderr)
    return 1 if len(failed) else 0


def _cmd_study_report(args: argparse.Namespace) -> int:
    from platoon_sumo.study.report import write_study_report

    print(f"study report written to {write_study_report(args.folder, args.out)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="platoon-sumo",
        description="Laser-based vehicle platoons co-simulated with Eclipse SUMO.",
    )
    parser.add_argument("--version", action="version", version=platoon_sumo.__version__)
    sub = parser.add_subparsers(dest="command", required=True)
    p_run = sub.add_parser("run", help="run a scenario and write a results folder")
    p_run.add_argument("scenario", nargs="?", help=f"scenario YAML (default: {DEFAULT_SCENARIO})")
    p_run.add_argument("--out", help="results folder (default: the scenario's outputs.directory)")
    p_run.add_argument("--end", type=float, help="override simulation.end_s [s]")
    p_run.add_argument("--seed", type=int, help="override simulation.seed")
    p_run.add_argument("--quiet", action="store_true", help="no progress line")
    p_run.add_argument(
        "--force", action="store_true",
        help="replace earlier results of ours in --out even if edited or unfinished "
        "(never files platoon-sumo did not write)",
    )  # fmt: skip
    p_run.add_argument(
        "--timings", action="store_true",
        help="write timings.csv: the CPU time of each stage of the loop, SUMO's step and each "
        "hook (costs about 20 µs a step)",
    )  # fmt: skip
    p_run.add_argument(
        "--no-platoons", action="store_true",
        help="run the same traffic without platoons (baseline for network effects)",
    )  # fmt: skip
    gui = p_run.add_argument_group(
        "live view", "watch the run in sumo-gui (same results as without; needs a display)"
    )
    gui.add_argument(
        "--gui", action="store_true",
        help="run in sumo-gui: platoons coloured by platoon (leader ringed), laser rays and "
        "hits, the followed vehicle's predecessor outlined in magenta",
    )  # fmt: skip
    gui.add_argument(
        "--gui-vehicle", metavar="ID",
        help="vehicle the view follows and whose rays are drawn (default: the first "
        "follower with a laser)",
    )  # fmt: skip
    gui.add_argument(
        "--gui-rays", choices=("chosen", "all", "none"), default="chosen",
        help="whose laser rays to draw (default: the followed vehicle's)",
    )  # fmt: skip
    gui.add_argument(
        "--gui-delay", type=float, default=100.0, metavar="MS",
        help="pause between steps [ms] (default 100; sumo-gui's toolbar changes it live)",
    )  # fmt: skip
    p_run.set_defaults(func=_cmd_run)
    p_scan = sub.add_parser("scan", help="run a scenario to a time and draw a laser scan as PNG")
    p_scan.add_argument("scenario", help="scenario YAML to run (nothing of the run is kept)")
    p_scan.add_argument(
        "--at", type=float, required=True, metavar="T",
        help="simulated time [s] at which to draw the scan (the latest scan by then)",
    )  # fmt: skip
    p_scan.add_argument(
        "--vehicle", metavar="ID",
        help="which platoon vehicle's laser, e.g. cars.2 (default: the first follower "
        "with a laser, else the first vehicle with one)",
    )  # fmt: skip
    p_scan.add_argument(
        "--out", metavar="PATH",
        help="PNG file (a name ending in .png, replaced if it exists), or a folder for a new "
        "laser_scan_<vehicle>_t<T>.png (default: the scenario's results folder, "
        "outputs.directory; a name already taken gets a number)",
    )  # fmt: skip
    p_scan.set_defaults(func=_cmd_scan)
    p_val = sub.add_parser("validate", help="check a scenario file without running it")
    p_val.add_argument(
        "scenario", help="scenario YAML: checked against its files and network, with warnings "
        "about signal phases and sensing",
    )  # fmt: skip
    p_val.set_defaults(func=_cmd_validate)
    p_rep = sub.add_parser("report", help="figures and report.md of a results folder")
    p_rep.add_argument("results", help="results folder of a finished run")
    p_rep.add_argument("--out", help="folder for the report (default: RESULTS/report)")
    p_rep.set_defaults(func=_cmd_report)
    p_ani = sub.add_parser(
        "animate", help="a video (MP4, or GIF) of a finished run following one vehicle"
    )
    p_ani.add_argument("results", help="results folder of a finished run")
    add = p_ani.add_argument
    add("--vehicle", help="platoon vehicle to follow and whose laser to draw "
        "(default: the first follower with a laser)")  # fmt: skip
    add("--from", dest="start_s", type=float,
        help="simulation time of the first frame [s] (default: the vehicle's first)")  # fmt: skip
    add("--to", dest="end_s", type=float,
        help="simulation time the video ends at [s] (default: the vehicle's last)")  # fmt: skip
    add("--out", help="video file, .mp4 or .gif (default: RESULTS/animation.mp4)")
    add("--fps", type=float, default=10.0,
        help="frames per second; a simulated second lasts a second (default: 10)")  # fmt: skip
    add("--size", type=_size, default=(800, 600),
        help="frame size WIDTHxHEIGHT in pixels, even numbers (default: 800x600)")  # fmt: skip
    add("--window", type=float, default=120.0,
        help="width of the view around the vehicle [m] (default: 120)")  # fmt: skip
    p_ani.add_argument("--quiet", action="store_true", help="no progress line")
    p_ani.set_defaults(func=_cmd_animate)
    p_cmp = sub.add_parser("compare", help="several runs' summaries and figures side by side")
    p_cmp.add_argument("results", nargs="+", help="results folders of finished runs")
    p_cmp.add_argument("--out", default="comparison", help="folder to write (default: comparison)")
    p_cmp.set_defaults(func=_cmd_compare)
    p_std = sub.add_parser(
        "study", help="run a parameter sweep with repetitions on Dask; one table out"
    )
    p_std.add_argument("study", help="study YAML (base scenario, parameters, metrics)")
    p_std.add_argument("--out", help="study folder (default: results/<study name>); "
                       "the same command again resumes it")  # fmt: skip
    p_std.add_argument("--workers", type=int, help="local worker processes (default: the cores)")
    p_std.add_argument(
        "--scheduler",
        help="address of a running Dask scheduler, e.g. tcp://host:8786 (the study folder "
        "must be reachable by its workers)",
    )
    p_std.add_argument("--quiet", action="store_true", help="no progress line")
    p_std.set_defaults(func=_cmd_study)
    p_srep = sub.add_parser(
        "study-report", help="figures of each metric against each parameter of a study"
    )
    p_srep.add_argument("folder", help="a study folder (platoon-sumo study --out)")
    p_srep.add_argument("--out", help="folder for the report (default: FOLDER/report)")
    p_srep.set_defaults(func=_cmd_study_report)
    return parser


def _on_sigterm(signum: int, frame: FrameType | None) -> None:
    raise Terminated()


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _on_sigterm) if main_thread else None
    try:
        return int(args.func(args))
    except (ScenarioError, FolderError, UsageError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except PlatoonSumoError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        terminated = isinstance(exc, Terminated)
        print(f"interrupted ({'SIGTERM' if terminated else 'Ctrl-C'})", file=sys.stderr)
        return 143 if terminated else 130
    except Exception as exc:  # a bug of ours: one line, the traceback on request
        if os.environ.get(TRACEBACK_ENV):
            raise
        where = "the run's FAILED.txt has it; " if args.command == "run" else ""
        print(
            f"error: internal error of platoon-sumo {platoon_sumo.__version__}: "
            f"{type(exc).__name__}: {exc} ({where}{TRACEBACK_ENV}=1 shows the traceback "
            "here; please report it)",
            file=sys.stderr,
        )
        return 1
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
