"""The co-simulation loop: SUMO moves the humans, we move the platoons.

A step is a fixed sequence of stages (`platoon_sumo.loop`) sharing one `StepContext`:

  before SUMO's step (on the world read after the previous one):
    RemovedElsewhere -> InsertDue -> Sense -> Decide -> Actuate
  SUMO's step, then (on the new world):
    SumoReports -> Gridlocks -> Arrivals -> ObserveWorld -> Departures -> ReadBack
    -> RouteProgress -> Standoffs -> LaneChangeGaps -> Footprints -> ObstaclesAhead -> Predecessors
    -> Cohesion -> SafetyCheck
  then every hook gets the step's immutable record.

docs/design.md walks through each stage. Stages exchange data through the context only,
so each can be tested alone on a fake backend. Given a `StageTimings`, the loop laps the
CPU clock after each stage, SUMO's step, the record and each hook (`--timings`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.collector import existing_objects_frozen
from platoon_sumo.events import Event
from platoon_sumo.loop.actuate import Actuate, ReadBack
from platoon_sumo.loop.context import (
    RunContext,
    RunOutcome,
    StepContext,
    StepHook,
    StepRecord,
    vehicle_columns,
)
from platoon_sumo.loop.decision import Decide
from platoon_sumo.loop.insertion import Arrivals, Departures, InsertDue, RemovedElsewhere
from platoon_sumo.loop.lane_change import LaneChangeGaps
from platoon_sumo.loop.observe import Footprints, Gridlocks, ObserveWorld, SumoReports
from platoon_sumo.loop.obstacles import ObstaclesAhead
from platoon_sumo.loop.ports import Backend
from platoon_sumo.loop.progress import RouteProgress
from platoon_sumo.loop.relations import Cohesion, Predecessors, SafetyCheck
from platoon_sumo.loop.sensing import Sense
from platoon_sumo.loop.standoff import Standoffs
from platoon_sumo.loop.timing import AFTER_SUMO, BEFORE_SUMO, HOOK, RECORD, SUMO, StageTimings
from platoon_sumo.scenario import PlatoonPlan, RunPlan

FloatArray = NDArray[np.float64]


class Stage(Protocol):
    """A step of the loop: reads and writes the shared context, nothing else."""

    def __call__(self, ctx: StepContext) -> None: ...


def before_sumo_stages() -> list[Stage]:
    return [RemovedElsewhere(), InsertDue(), Sense(), Decide(), Actuate()]


def after_sumo_stages() -> list[Stage]:
    return [
        SumoReports(), Gridlocks(), Arrivals(), ObserveWorld(), Departures(), ReadBack(),
        RouteProgress(), Standoffs(), LaneChangeGaps(), Footprints(), ObstaclesAhead(),
        Predecessors(), Cohesion(), SafetyCheck(),
    ]  # fmt: skip


class CoSimulation:
    """Runs a RunPlan on a started backend; `run()` steps until the end time."""

    def __init__(
        self,
        plan: RunPlan,
        backend: Backend,
        hooks: Sequence[StepHook] = (),
        rng: np.random.Generator | None = None,
        static_segments: FloatArray | None = None,
        timings: StageTimings | None = None,
    ):
        sim = plan.scenario.simulation
        self.run_context = RunContext(plan, sim.step_s, sim.begin_s, sim.end_s, static_segments)
        self.backend = backend
        self.hooks = list(hooks)
        self.before_sumo: list[Stage] = before_sumo_stages()
        self.after_sumo: list[Stage] = after_sumo_stages()
        self.ctx = StepContext(
            self.run_context,
            backend,
            rng if rng is not None else np.random.default_rng(sim.seed),
            pending=sorted(plan.platoons, key=lambda p: (p.config.depart_s, p.config.id)),
        )
        self.events: list[Event] = []
        """Every event of the run so far, in order."""
        self.timings = timings
        """The CPU time of each stage, SUMO's step and each hook, when asked for."""

    @property
    def end_s(self) -> float:
        return self.run_context.end_s

    @property
    def pending_platoons(self) -> list[PlatoonPlan]:
        """Platoons never inserted (their depart time or first-lane room not yet come)."""
        return list(self.ctx.pending)

    @property
    def queued_members(self) -> list[str]:
        """Members of inserted platoons still waiting for room on their first edge."""
        return [m.vehicle_id for _, rest in self.ctx.queued.values() for m in rest]

    def run(self) -> RunOutcome:
        """Step to the end time. Every hook's `on_end` runs, also when a stage or hook
        fails or the run is interrupted, so recorders keep every row produced."""
        for hook in self.hooks:
            hook.on_start(self.run_context)
        outcome = RunOutcome("failed", self.backend.time_s)
        try:
            self.ctx.world = self.backend.snapshot([], 0.0)
            with existing_objects_frozen():  # built for the run: nothing to collect there
                while self.backend.time_s < self.end_s - 1e-9:
                    self.step()
            outcome = RunOutcome("complete", self.backend.time_s)
        except KeyboardInterrupt:  # the time of the last world read: SUMO may be gone
            outcome = RunOutcome("interrupted", self.ctx.world.time_s, "interrupted")
            raise
        except BaseException as exc:
            reason = f"{type(exc).__name__}: {exc}"
            outcome = RunOutcome("failed", self.ctx.world.time_s, reason)
            raise
        finally:
            self._end_hooks(outcome)
        return outcome

    def _end_hooks(self, outcome: RunOutcome) -> None:
        first: BaseException | None = None
        for hook in self.hooks:
            try:
                hook.on_end(outcome)
            except BaseException as exc:  # every hook still gets its end
                first = first or exc
        if first is not None and outcome.status == "complete":
            raise first

    def step(self) -> StepRecord:
        ctx, timings = self.ctx, self.timings
        ctx.events = []
        if timings is not None:
            timings.start()
        _run_stages(self.before_sumo, ctx, timings, BEFORE_SUMO)
        self.backend.step()
        ctx.steps += 1
        if timings is not None:
            timings.lap("SUMO step", SUMO)
        _run_stages(self.after_sumo, ctx, timings, AFTER_SUMO)
        self.events.extend(ctx.events)
        record = StepRecord(
            time_s=ctx.world.time_s,
            world=ctx.world,
            footprints=ctx.footprints,
            sensed_world=ctx.sensed_world,
            sensed_footprints=ctx.sensed_footprints,
            columns=vehicle_columns(ctx.fleet),
            events=tuple(ctx.events),
            sumo_vehicles=self.backend.vehicle_count(),
        )
        if timings is not None:
            timings.lap("step record", RECORD)
        for hook in self.hooks:
            hook.on_step(record)
            if timings is not None:
                timings.lap(type(hook).__name__, HOOK)
        if timings is not None:
            timings.end_step(len(record.columns))
        return record


def _run_stages(
    stages: Sequence[Stage], ctx: StepContext, timings: StageTimings | None, kind: str
) -> None:
    for stage in stages:
        stage(ctx)
        if timings is not None:
            timings.lap(type(stage).__name__, kind)
