"""One run of a scenario, from file to results folder.

The folder holds the scenario file, the generated inputs, the trajectory table, SUMO's
tripinfo and `summary.json`. `summary.json` is written last, with status "complete";
a run that fails leaves `FAILED.txt` instead, so half-written results never pass for
complete ones.
"""

from __future__ import annotations

import dataclasses
import json
import platform
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

import platoon_sumo
from platoon_sumo.collector import collector_paused
from platoon_sumo.config_loader import FieldError
from platoon_sumo.control.base import SumoCarFollowing
from platoon_sumo.cosim import CoSimulation
from platoon_sumo.errors import ScenarioError
from platoon_sumo.events import WALL, Event, EventKind, count, of_kind
from platoon_sumo.live_view import LiveView, LiveViewOptions
from platoon_sumo.loop.context import StepHook
from platoon_sumo.loop.timing import OUTSIDE, StageTimings
from platoon_sumo.metrics import RunStats
from platoon_sumo.metrics.sumo_outputs import (
    EDGEDATA_FILE,
    PERSONINFO_FILE,
    SUMO_SUMMARY_FILE,
    person_summary,
    read_run_outputs,
    sumo_output_args,
    traffic_effect,
    write_edgedata_additional,
)
from platoon_sumo.metrics.tables import by_id, overall, summary_tables, write_table
from platoon_sumo.recorder import EventWriter, ScanSnapshot, TrajectoryRecorder
from platoon_sumo.results import COMPLETE, FAILED, INTERRUPTED, claim
from platoon_sumo.scenario import PlatoonPlan, RunPlan, ScenarioSource, load_scenario, prepare
from platoon_sumo.scene_recorder import SCANS_FILE, SCENE_FILE, SceneRecorder
from platoon_sumo.sumo.backend import (
    SumoBackend,
    SumoOptions,
    sumo_version,
    write_car_following_types,
)
from platoon_sumo.sumo.shapes import read_wall_segments
from platoon_sumo.traffic import write_traffic_inputs

#: CPU time of each part of the loop (`run(timings=True)`, `platoon-sumo run --timings`).
TIMINGS_FILE = "timings.csv"
#: Every name a run writes at the top of its folder (its report included): a file of the
#: user's under one of these names keeps the run out of the folder.
OUTPUT_NAMES = frozenset({
    "summary.json", "FAILED.txt", "scenario.yaml", "trajectories.csv", "trajectories.parquet",
    "tripinfo.csv", "sumo_statistics.xml", "vehicles.csv", "platoons.csv", SUMO_SUMMARY_FILE,
    EDGEDATA_FILE, PERSONINFO_FILE, "scan_snapshot.npz", "events.csv", "inputs", "report",
    SCENE_FILE, SCANS_FILE, TIMINGS_FILE,
})  # fmt: skip


@dataclass(frozen=True)
class RunResult:
    directory: Path
    summary: dict[str, Any]


def load_plan(
    path: str | Path,
    end_s: float | None = None,
    seed: int | None = None,
    without_platoons: bool = False,
) -> RunPlan:
    """Load and check a scenario, with command-line overrides applied.

    `without_platoons` runs the same traffic with no platoon at all: the baseline that
    shows what the platoons do to everyone else. The garbage collector pauses meanwhile:
    the scenario, network, routes and paths are objects that all live on."""
    with collector_paused():
        return _load_plan(path, end_s, seed, without_platoons)


def _load_plan(
    path: str | Path, end_s: float | None, seed: int | None, without_platoons: bool
) -> RunPlan:
    source = load_scenario(path)
    if without_platoons:
        source = ScenarioSource(
            dataclasses.replace(source.scenario, platoons=()), source.path, source.text
        )
    sim = source.scenario.simulation
    changes: dict[str, Any] = {}
    if end_s is not None:
        changes["end_s"] = end_s
    if seed is not None:
        changes["seed"] = seed
    if changes:
        try:
            new_sim = dataclasses.replace(sim, **changes)
        except FieldError as exc:
            option = {"end_s": "--end", "seed": "--seed"}.get(exc.key, exc.key)
            raise ScenarioError(
                str(path), f"simulation.{exc.key}", f"{option} {exc.message}", exc.hint
            ) from None
        source = ScenarioSource(
            dataclasses.replace(source.scenario, simulation=new_sim), source.path, source.text
        )
    return prepare(source)


def results_directory(plan: RunPlan) -> Path:
    """The plan's results folder: `outputs.directory`, default `results/<name>`, relative
    to the working directory."""
    sc = plan.scenario
    return Path(sc.outputs.directory or Path("results") / sc.name)


def run(
    plan: RunPlan,
    out_dir: str | Path | None = None,
    hooks: Sequence[StepHook] = (),
    force: bool = False,
    live_view: LiveViewOptions | None = None,
    timings: bool = False,
) -> RunResult:
    """Run `plan` into a results folder that is new, empty or holds our earlier results
    (`results.claim`; `force` replaces earlier results that were edited or never
    finished). A failed or interrupted run keeps what it wrote, with FAILED.txt (the
    reason and its traceback) and its manifest saying so. `live_view` runs it in
    sumo-gui with the live view drawn (the same results, slower). `timings` writes the
    CPU time of each stage, SUMO's step and each hook to `timings.csv`."""
    sc = plan.scenario
    directory = Path(out_dir or results_directory(plan)).resolve()
    folder = claim(directory, "run", OUTPUT_NAMES, force)
    try:
        (directory / "scenario.yaml").write_text(
            plan.source.reproducible_yaml(sc.simulation), encoding="utf-8"
        )
        result = _run(plan, directory, hooks, live_view, StageTimings() if timings else None)
    except BaseException as exc:
        reason = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
        trace = "".join(traceback.format_exception(exc))
        (directory / "FAILED.txt").write_text(
            f"{reason}: {type(exc).__name__}: {exc}\n\n{trace}", encoding="utf-8"
        )
        folder.finish(INTERRUPTED if reason == "interrupted" else FAILED)
        raise
    folder.finish(COMPLETE)
    return result


def _run(
    plan: RunPlan, directory: Path, hooks: Sequence[StepHook], live_view: LiveViewOptions | None,
    timings: StageTimings | None,
) -> RunResult:  # fmt: skip
    thread_cpu_start = time.thread_time()
    sc = plan.scenario
    generated = write_traffic_inputs(plan, directory / "inputs")
    out = sc.outputs
    extra_additional: tuple[str, ...] = ()
    if out.sumo_outputs:
        edge_add = write_edgedata_additional(directory / "inputs", directory, out.edgedata_period_s)
        extra_additional = (str(edge_add),)
    types = _vehicle_types(plan)
    models = {f"{t}_model": {"carFollowModel": cf.model, **cf.attributes}
              for t, _, cf in types if cf is not None}  # fmt: skip
    if models:
        path = directory / "inputs" / "car_following_types.add.xml"
        extra_additional += (str(write_car_following_types(path, models)),)
    options = SumoOptions(
        net_file=str(plan.net_file),
        step_s=sc.simulation.step_s,
        seed=sc.simulation.seed,
        begin_s=sc.simulation.begin_s,
        route_files=tuple(str(p) for p in (*plan.route_files, *generated)),
        additional_files=(*(str(p) for p in plan.additional_files), *extra_additional),
        lateral_resolution_m=sc.simulation.lateral_resolution_m,
        time_to_teleport_s=sc.simulation.time_to_teleport_s,
        demand_scale=sc.traffic.scale,
        tripinfo_file=str(directory / "tripinfo.csv") if sc.outputs.tripinfo else None,
        statistics_file=str(directory / "sumo_statistics.xml"),
        extra_args=sumo_output_args(directory) if out.sumo_outputs else (),
        gui=live_view is not None,
        gui_delay_ms=live_view.delay_ms if live_view is not None else 0.0,
    )
    stats = RunStats(
        {p.config.id: len(p.members) for p in plan.platoons}, out.metrics_start_s,
        {p.config.id: (p.limits.max_accel_mps2, p.limits.max_decel_mps2, p.limits.max_speed_mps)
         for p in plan.platoons},
    )  # fmt: skip
    trajectories = directory / f"trajectories.{out.format}"
    recorder = TrajectoryRecorder(
        trajectories, out.chunk_rows, out.format, stats, write=out.trajectories
    )
    all_hooks: list[StepHook] = [recorder, EventWriter(directory / "events.csv")]
    snapshot = None
    if any(m.laser is not None for p in plan.platoons for m in p.members):
        snapshot = ScanSnapshot(out.scan_snapshot_s)
        all_hooks.append(snapshot)
    if out.scene_period_s is not None:
        all_hooks.append(SceneRecorder(directory, out.scene_period_s, out.scene_radius_m))
    all_hooks.extend(hooks)
    if live_view is not None:
        all_hooks.append(LiveView(live_view))
    walls = read_wall_segments(plan.additional_files)
    if sc.network.kerbs:
        walls = np.vstack([walls, plan.network.kerb_segments(sc.network.kerb_margin_m)])
    wall_start = time.perf_counter()
    backend = SumoBackend(options)
    backend.start()
    try:
        for type_id, platoon, cf in types:
            v = platoon.config.vehicle
            min_gap = v.min_gap_m if cf is None or cf.min_gap_m is None else cf.min_gap_m
            backend.add_vehicle_type(
                type_id, v.length_m, v.width_m, min_gap, v.max_speed_mps, v.max_accel_mps2,
                v.max_decel_mps2, v.vclass, v.sumo_tau_s if cf is None else cf.tau_s,
                v.sumo_speed_factor, "DEFAULT_VEHTYPE" if cf is None else f"{type_id}_model",
            )  # fmt: skip
        sim = CoSimulation(
            plan,
            backend,
            all_hooks,
            rng=np.random.default_rng(sc.simulation.seed),
            static_segments=walls if len(walls) else None,
            timings=timings,
        )
        sim.run()
        end_time = backend.time_s
        vehicle_classes = backend.vehicle_classes()
    finally:
        backend.close()
    wall_s = time.perf_counter() - wall_start
    summary = _summary(plan, sim, end_time, wall_s)
    summary["followers"] = stats.followers()
    trips, sumo_summary, edgedata, persons = read_run_outputs(directory)
    vehicles, platoons, responses = summary_tables(
        stats, trips, trajectories if out.trajectories else None
    )
    write_table(directory / "vehicles.csv", vehicles)
    write_table(directory / "platoons.csv", platoons)
    summary["platoons"] = by_id(platoons, "platoon_id")
    summary["string_stability"] = responses
    summary["overall"] = overall(platoons)
    platoon_ids = [m.vehicle_id for p in plan.platoons for m in p.members]
    route_edges = sorted({e for p in plan.platoons for e in p.edges})
    summary["traffic"] = {
        **traffic_effect(trips, platoon_ids, sumo_summary, edgedata, route_edges, vehicle_classes),
        **person_summary(persons),
    }
    if snapshot is not None:
        snapshot.save(directory / "scan_snapshot.npz")
    if timings is not None:
        loop_s = sum(timings.cpu_s.values())
        timings.add("start and end", OUTSIDE, time.thread_time() - thread_cpu_start - loop_s)
        timings.table().to_csv(directory / TIMINGS_FILE, index=False)
    with (directory / "summary.json").open("w") as f:
        json.dump(summary, f, indent=2)
    return RunResult(directory, summary)


def _vehicle_types(plan: RunPlan) -> list[tuple[str, PlatoonPlan, SumoCarFollowing | None]]:
    """Every SUMO type the platoons need: each platoon's, and a role's own where SUMO's
    car-following model drives its members (with that model)."""
    types: dict[str, tuple[str, PlatoonPlan, SumoCarFollowing | None]] = {}
    for platoon in plan.platoons:
        types[platoon.type_id] = (platoon.type_id, platoon, None)
        for member in platoon.members:
            type_id = platoon.type_id_of(member)
            types.setdefault(type_id, (type_id, platoon, member.sumo_car_following))
    return list(types.values())


def _summary(plan: RunPlan, sim: CoSimulation, end_time_s: float, wall_s: float) -> dict[str, Any]:
    sc = plan.scenario
    sim_s = end_time_s - sc.simulation.begin_s
    planned = sum(len(p.members) for p in plan.platoons)
    ctx, events = sim.ctx, sim.events
    return {
        "status": "complete",
        "scenario": sc.name,
        "scenario_file": str(plan.source.path),
        "scenario_sha256": plan.source.sha256,
        "seed": sc.simulation.seed,
        "network_file": str(plan.net_file),
        "trajectory_format": sc.outputs.format if sc.outputs.trajectories else None,
        "metrics_start_s": sc.outputs.metrics_start_s,
        "versions": {
            "platoon_sumo": platoon_sumo.__version__,
            "sumo": sumo_version(),
            "python": platform.python_version(),
            "numpy": np.__version__,
            "pandas": pd.__version__,
        },
        "simulated_s": sim_s,
        "wall_clock_s": round(wall_s, 3),
        "real_time_factor": round(sim_s / wall_s, 2) if wall_s > 0 else None,
        "steps": ctx.steps,
        "platoon_vehicles": {
            "planned": planned,
            "departed": count(events, EventKind.DEPARTED),
            "arrived": count(events, EventKind.ARRIVED),
            "still_running": len(ctx.fleet),
        },
        "all_vehicles": {"departed": ctx.departed_total, "arrived": ctx.arrived_total},
        "platoons_not_inserted": sorted(p.config.id for p in sim.pending_platoons),
        "members_not_inserted": sorted(sim.queued_members),
        **event_summary(events, {m.vehicle_id for p in plan.platoons for m in p.members}),
    }


def event_summary(events: list[Event], platoon_vehicle_ids: set[str]) -> dict[str, Any]:
    """The summary's counts and logs, all from the run's event stream."""
    contacts = of_kind(events, EventKind.COLLISION, EventKind.WALL_CONTACT)
    sumo = of_kind(events, EventKind.SUMO_COLLISION)
    red = of_kind(events, EventKind.RED_LIGHT)
    structure = of_kind(events, EventKind.SPLIT, EventKind.REFORMATION, EventKind.CUT_IN)
    return {
        "collisions": len(contacts),
        "collisions_platoon_at_fault": sum(e.at_fault in platoon_vehicle_ids for e in contacts),
        "collision_events": [
            dict(
                zip(
                    ("time_s", "vehicle_a", "vehicle_b", "at_fault"),
                    (
                        e.time_s,
                        *sorted((e.vehicle_id, e.other_id), key=lambda v: (v == WALL, v)),
                        e.at_fault or None,
                    ),
                    strict=True,
                )
            )
            for e in contacts
        ],
        "sumo_collisions": len(sumo),
        "sumo_collisions_with_platoons": sum(
            e.vehicle_id in platoon_vehicle_ids or e.other_id in platoon_vehicle_ids for e in sumo
        ),
        "sumo_collisions_platoon_at_fault": sum(e.at_fault in platoon_vehicle_ids for e in sumo),
        "teleports": count(events, EventKind.TELEPORT),
        "gridlocks": count(events, EventKind.GRIDLOCK),
        "gridlock_events": [
            {"time_s": e.time_s, "vehicle_id": e.vehicle_id, "where": e.detail}
            for e in of_kind(events, EventKind.GRIDLOCK)
        ],
        "emergency_brakings": count(events, EventKind.EMERGENCY_BRAKING),
        "standoffs": count(events, EventKind.STANDOFF),
        "sumo_speed_caps": count(events, EventKind.SUMO_SPEED_CAP),
        "red_light_violations": len(red),
        "red_light_events": [
            {
                "time_s": e.time_s,
                "vehicle_id": e.vehicle_id,
                "tls_id": e.other_id,
                "link_index": int(e.detail.split()[1]),
                "state": e.detail.split()[2],
            }
            for e in red
        ],
        "removed_off_route": [
            {"time_s": e.time_s, "vehicle_id": e.vehicle_id, "reason": e.detail}
            for e in of_kind(events, EventKind.REMOVED)
        ],
        "platoon_events": {
            kind.value + "s": count(structure, kind)
            for kind in (EventKind.SPLIT, EventKind.REFORMATION, EventKind.CUT_IN)
        },
        "platoon_event_log": [
            {
                "time_s": e.time_s,
                "platoon_id": e.platoon_id,
                "follower_id": e.vehicle_id,
                "kind": e.kind.value,
                "other_id": e.other_id,
            }
            for e in structure
        ],
    }
