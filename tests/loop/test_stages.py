"""Each stage of the loop alone, on the fake backend (tests/fakes.py): the data it reads
from the step context and what it writes back, events included."""

from __future__ import annotations

import gc
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

from platoon_sumo.collector import INTERPRETER_FROZEN
from platoon_sumo.control import Command
from platoon_sumo.cosim import CoSimulation
from platoon_sumo.errors import PluginError
from platoon_sumo.events import EventKind
from platoon_sumo.fault import FRONT, PLACED, PLACED_RECENTLY
from platoon_sumo.loop.actuate import Actuate, ReadBack
from platoon_sumo.loop.context import RunContext, RunOutcome, StepContext, StepHook
from platoon_sumo.loop.decision import Decide
from platoon_sumo.loop.insertion import Departures, InsertDue, RemovedElsewhere
from platoon_sumo.loop.observe import Footprints, Gridlocks, ObserveWorld, SumoReports
from platoon_sumo.loop.obstacles import ObstaclesAhead
from platoon_sumo.loop.progress import RouteProgress, link_ahead
from platoon_sumo.loop.relations import Cohesion, Predecessors, SafetyCheck
from platoon_sumo.loop.sensing import Sense
from platoon_sumo.loop.standoff import FOES_STILL_S, STANDOFF_S, Standoffs
from platoon_sumo.runner import load_plan
from platoon_sumo.scenario import RunPlan
from platoon_sumo.vehicles import Bicycle
from platoon_sumo.world import LinkAhead, VehicleAhead
from tests.fakes import LANE_Y_M, FakeBackend, FakeVehicle
from tests.helpers import REPO

PLUGINS = Path(__file__).resolve().parents[1] / "plugins"


@dataclass(frozen=True)
class NoParams:
    pass


class Scripted:
    """A controller whose command is whatever `Scripted.speed` says (or raises)."""

    Params = NoParams
    speed: Any = 5.0

    def __init__(self, params: Any = None) -> None:
        pass

    def reset(self) -> None:
        pass

    def step(self, observation: Any) -> Any:
        if isinstance(Scripted.speed, Exception):
            raise Scripted.speed
        return Command(Scripted.speed) if isinstance(Scripted.speed, float) else Scripted.speed


SCRIPTED = {"type": "tests.loop.test_stages:Scripted"}


def plan(write_scenario, actuation: str = "lane", members: int = 2, **extra: Any) -> RunPlan:
    data = {
        "simulation": {"step_s": 0.1, "end_s": 20.0, "lateral_resolution_m": 0.8},
        "network": {"net_file": str(REPO / "networks" / "straight" / "straight.net.xml")},
        "platoons": [{
            "id": "p", "route": {"edges": ["WE"]}, "members": members, "spacing_m": 5.0,
            "depart_pos_m": 100.0, "actuation": actuation,
            # an ideal powertrain: the commands reach the actuator unchanged
            "vehicle": {"model": "bicycle", "length_m": 4.5, "width_m": 1.8,
                        "actuator_lag_s": 0.0},
            "leader": {"type": "route_following"}, "follower": {"type": "route_following"},
            **extra,
        }],
    }  # fmt: skip
    return load_plan(write_scenario(data))


def context(run_plan: RunPlan, backend: FakeBackend) -> StepContext:
    sim = run_plan.scenario.simulation
    run = RunContext(run_plan, sim.step_s, sim.begin_s, sim.end_s, None)
    return StepContext(run, backend, np.random.default_rng(0), pending=list(run_plan.platoons))


def departed(ctx: StepContext, backend: FakeBackend) -> None:
    """Insert the platoon and let it depart (one fake SUMO step)."""
    InsertDue()(ctx)
    backend.step()
    ObserveWorld()(ctx)
    Departures()(ctx)
    Footprints()(ctx)


def test_insert_waits_for_room_on_the_first_lane_then_hands_over_the_whole_platoon(
    write_scenario,
):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=3), backend)
    backend.add_human("h", 95.0, 0.0)  # inside the platoon's depart stretch
    InsertDue()(ctx)
    assert backend.queued == [] and len(ctx.pending) == 1
    backend.vehicles.pop("h")
    InsertDue()(ctx)
    assert [vid for vid, _ in backend.queued] == ["p.0", "p.1", "p.2"]
    assert all(v.sumo_drives for _, v in backend.queued)  # lane actuation: SUMO drives
    assert ctx.pending == [] and set(ctx.waiting) == {"p.0", "p.1", "p.2"}


def test_members_beyond_the_first_edge_follow_one_by_one_when_the_one_ahead_left_room(
    write_scenario,
):
    # leader at 20 m, slots of 4.5 + 5 m: members 0 and 1 fit, 2 and 3 wait at 10.5 m
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=4, depart_pos_m=20.0), backend)
    members = ctx.pending[0].members
    assert [m.waits_for_room for m in members] == [False, False, True, True]
    assert [m.depart_pos_m for m in members] == [20.0, 10.5, 10.5, 10.5]
    InsertDue()(ctx)
    assert [vid for vid, _ in backend.queued] == ["p.0", "p.1"]
    InsertDue()(ctx)  # p.1 has not departed yet: p.2 waits
    assert [vid for vid, _ in backend.queued] == ["p.0", "p.1"]
    backend.step()
    ctx.waiting.clear()  # (Departures' job)
    InsertDue()(ctx)  # departed, but p.1 still covers the slot
    assert backend.queued == []
    backend.vehicles["p.1"].x_m = 10.5 + 4.5 + 5.0 - 0.01  # not quite a spacing ahead
    InsertDue()(ctx)
    assert backend.queued == []
    backend.vehicles["p.1"].x_m = 10.5 + 4.5 + 5.0 + 0.01
    InsertDue()(ctx)
    assert [vid for vid, _ in backend.queued] == ["p.2"]  # one at a time, in order
    assert ctx.queued["p"][1] == [members[3]]
    backend.step()
    ctx.waiting.clear()
    backend.vehicles["p.2"].x_m = 30.0
    InsertDue()(ctx)
    assert [vid for vid, _ in backend.queued] == ["p.3"] and ctx.queued == {}


def test_a_member_taken_out_of_sumo_elsewhere_leaves_the_fleet_as_removed(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario), backend)
    departed(ctx, backend)
    backend.vanished = ["p.0", "someone"]  # a hook removed a member and a human
    ctx.events = []
    RemovedElsewhere()(ctx)
    assert ctx.fleet.ids() == ["p.1"]
    assert [(e.kind, e.vehicle_id) for e in ctx.events] == [(EventKind.REMOVED, "p.0")]


def test_departures_build_members_from_sumo_poses_and_emit_departed(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario), backend)
    departed(ctx, backend)
    assert ctx.fleet.ids() == ["p.0", "p.1"]
    leader = ctx.fleet.get("p.0")
    assert leader is not None
    assert leader.front_bumper() == pytest.approx((100.0, LANE_Y_M))
    assert leader.route_s_m == pytest.approx(100.0, abs=0.01)
    assert [e.kind for e in ctx.events] == [EventKind.DEPARTED, EventKind.DEPARTED]
    assert ctx.waiting == {}


def test_world_holds_platoon_vehicles_and_their_neighbours_only(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario), backend)
    # no sensors: the radius is the largest platoon vehicle plus the largest vehicle
    # (4.5 + 1.8 m each here), 12.6 m from a front bumper
    backend.add_human("near", 110.0, 0.0)  # front 10 m ahead of p.0's
    backend.add_human("beyond", 113.0, 0.0)  # 13 m: out of reach
    backend.add_human("far", 900.0, 10.0)
    departed(ctx, backend)
    assert set(ctx.world.ids) == {"p.0", "p.1", "near"}
    assert ctx.footprints.shape == (3, 5)


def test_decide_supervises_and_counts_an_emergency_once_per_episode(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1, leader=SCRIPTED), backend)
    backend.add_human("stopped", 110.0, 0.0)  # 5.5 m ahead of the leader's bumper
    departed(ctx, backend)
    RouteProgress()(ctx)
    Scripted.speed = 15.0
    for _ in range(3):
        ctx.events = []
        Decide()(ctx)
    (m,) = list(ctx.fleet)
    assert m.command.speed_mps == 15.0 and m.executed.speed_mps < 15.0
    assert m.supervisor_state == "emergency"
    ctx.events = []
    Decide()(ctx)
    assert ctx.events == []  # the same episode: counted when it began


class Watching(Scripted):
    """`Scripted`, keeping every observation it is given."""

    seen: ClassVar[list[Any]] = []

    def step(self, observation: Any) -> Any:
        Watching.seen.append(observation)
        return super().step(observation)


def test_the_observation_a_controller_gets_is_the_frozen_dataclass_of_its_fields(
    write_scenario,
):
    """Decide builds observations without the dataclass's `__init__` (for speed): what a
    controller gets must be the same value, frozen, and work with `dataclasses`."""
    import dataclasses

    from platoon_sumo.control import Observation

    backend = FakeBackend()
    leader = {"type": "tests.loop.test_stages:Watching"}
    ctx = context(plan(write_scenario, members=1, leader=leader), backend)
    departed(ctx, backend)
    RouteProgress()(ctx)
    Scripted.speed, Watching.seen = 5.0, []
    Decide()(ctx)
    (obs,) = Watching.seen
    fields = {f.name: getattr(obs, f.name) for f in dataclasses.fields(Observation)}
    assert type(obs) is Observation and obs == Observation(**fields)
    assert dataclasses.asdict(obs).keys() == fields.keys()
    assert dataclasses.replace(obs, speed_mps=1.0).speed_mps == 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        obs.speed_mps = 1.0
    assert obs.vehicle_id == "p.0" and obs.path is not None


def test_a_member_sumo_drives_is_only_checked_never_reported_braking(write_scenario):
    """`sumo_driver`: SUMO's model drives the speed, so the supervisor's emergency is a
    mark in its state, not an emergency braking event (nothing braked), and the speed
    handed to SUMO stays its own model's (-1)."""
    backend = FakeBackend()
    sumo_driver = {"type": "sumo_driver", "params": {"car_follow_model": "Krauss"}}
    ctx = context(plan(write_scenario, members=1, leader=sumo_driver), backend)
    backend.add_human("stopped", 110.0, 0.0)  # 5.5 m ahead of the leader's bumper
    departed(ctx, backend)
    backend.vehicles["p.0"].speed_mps = 15.0  # SUMO's model drove it up fast
    ObserveWorld()(ctx)
    ReadBack()(ctx)
    RouteProgress()(ctx)
    ctx.events = []
    Decide()(ctx)
    (m,) = list(ctx.fleet)
    assert m.supervisor_state == "emergency"
    assert ctx.events == []
    Actuate()(ctx)
    assert backend.speed_commands == {"p.0": -1.0}


class LinkBackend(FakeBackend):
    """The fake road ends 40 m ahead at a minor link; records which links it was asked
    to read with the route contexts, and every later read."""

    def __init__(self) -> None:
        super().__init__()
        self.read_links: list[bool] = []
        self.later_reads: list[tuple[str, float]] = []

    def route_contexts(self, vehicle_ids, horizons_m, read_links):
        self.read_links = list(read_links)
        contexts = super().route_contexts(vehicle_ids, horizons_m, read_links)
        return [
            (signal, ahead, LinkAhead("m", False, False, True, 40.0) if read else 40.0)
            for (signal, ahead, _), read in zip(contexts, read_links, strict=True)
        ]

    def link_ahead(self, vehicle_id: str, distance_m: float) -> LinkAhead | None:
        self.later_reads.append((vehicle_id, distance_m))
        return LinkAhead("m", False, False, True, distance_m)


class Unlinked(Scripted):
    """`Scripted`, declaring that it never reads `link_ahead`."""

    reads_link_ahead: ClassVar[bool] = False


class LinkedChild(Unlinked):
    """A plug-in built on `Unlinked` that does not say it: it may read the link."""


@pytest.mark.parametrize(
    ("actuation", "leader", "read"),
    [
        ("lane", "tests.loop.test_stages:Scripted", True),  # a plug-in may read it
        ("lane", "tests.loop.test_stages:Unlinked", False),  # SUMO gives way for it
        ("lane", "tests.loop.test_stages:LinkedChild", True),  # the flag is not inherited
        ("planar", "tests.loop.test_stages:Unlinked", True),  # the supervisor yields
    ],
)
def test_sumos_link_query_is_made_where_the_link_may_be_read(
    write_scenario, actuation: str, leader: str, read: bool
):
    """SUMO's link query walks every link left on the route, the dearest per-vehicle
    read: `RouteProgress` makes it for a member whose controller may read the link or
    whose supervisor yields at junctions (SUMO does not drive it), and leaves the others
    the lane end's distance, read if a stage asks (`loop.progress.link_ahead`)."""
    backend = LinkBackend()
    ctx = context(plan(write_scenario, actuation, members=1, leader={"type": leader}), backend)
    departed(ctx, backend)
    RouteProgress()(ctx)
    (m,) = list(ctx.fleet)
    assert backend.read_links == [read]
    if read:
        assert m.link_ahead == LinkAhead("m", False, False, True, 40.0) and m.lane_end_m is None
    else:
        assert m.link_ahead is None and m.lane_end_m == 40.0
        assert link_ahead(ctx, m) == LinkAhead("m", False, False, True, 40.0)
        assert link_ahead(ctx, m) is m.link_ahead and m.lane_end_m is None
        assert backend.later_reads == [("p.0", 40.0)]  # once


def test_standoffs_read_a_link_left_unread_only_for_a_car_standing_at_it(write_scenario):
    """The standoff rule needs the link's right of way only for a car standing within
    `AT_LINK_M` of it; a moving car, or one farther, costs no link query."""
    backend = LinkBackend()
    leader = {"type": "tests.loop.test_stages:Unlinked"}
    ctx = context(plan(write_scenario, members=1, leader=leader), backend)
    departed(ctx, backend)
    (m,) = list(ctx.fleet)
    standoffs = Standoffs()
    for end_m, speed_mps, reads in ((40.0, 0.0, 0), (2.0, 3.0, 0), (2.0, 0.0, 1)):
        m.link_ahead, m.lane_end_m = None, end_m
        backend.vehicles["p.0"].speed_mps = speed_mps
        ObserveWorld()(ctx)
        backend.later_reads = []
        standoffs(ctx)
        assert len(backend.later_reads) == reads


def test_a_failing_controller_is_named_with_its_vehicle_and_time(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1, leader=SCRIPTED), backend)
    departed(ctx, backend)
    Scripted.speed = ValueError("boom")
    with pytest.raises(PluginError, match=r"Scripted of vehicle 'p.0' failed at t=0.10 s.*boom"):
        Decide()(ctx)
    Scripted.speed = "not a command"
    with pytest.raises(PluginError, match="returned str"):
        Decide()(ctx)
    Scripted.speed = 5.0


def test_lane_actuation_hands_speeds_and_lane_requests_to_sumo(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario), backend)
    departed(ctx, backend)
    for m in ctx.fleet:
        m.executed = Command(7.0, lane_change=1 if m.index else 0)
    Actuate()(ctx)
    assert backend.speed_commands == {"p.0": 7.0, "p.1": 7.0}
    assert backend.lane_requests == {"p.1": 1}


def test_a_cars_default_powertrain_lags_the_speed_sent(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, vehicle={"model": "bicycle"}), backend)
    departed(ctx, backend)
    for m in ctx.fleet:
        m.executed = Command(7.0)
    Actuate()(ctx)
    # from standstill the lag lets through 1 - e^(-dt / lag) of the acceleration asked for
    lag_s, limits = Bicycle.default_actuator_lag_s, ctx.run.plan.platoons[0].limits
    sent = (1.0 - math.exp(-0.1 / lag_s)) * limits.max_accel_mps2 * 0.1
    assert backend.speed_commands == pytest.approx({"p.0": sent, "p.1": sent})


def test_read_back_names_sumo_capping_the_speed_once_per_episode(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)
    (m,) = list(ctx.fleet)
    m.executed = Command(10.0)
    m.speed_sent_mps = 10.0  # what Actuate handed SUMO
    for _ in range(3):  # SUMO keeps it standing (its safety layer)
        backend.speed_commands["p.0"] = 0.0
        backend.step()
        ObserveWorld()(ctx)
        ReadBack()(ctx)
    assert m.supervisor_state == "sumo"
    assert [e.kind for e in ctx.events].count(EventKind.SUMO_SPEED_CAP) == 1


def test_planar_actuation_moves_the_model_and_takes_out_what_sumo_cannot_place(
    write_scenario,
):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, actuation="planar"), backend)
    departed(ctx, backend)
    follower = ctx.fleet.get("p.1")
    assert follower is not None
    follower.y_m += 50.0  # far off the road: SUMO cannot place it
    for m in ctx.fleet:
        m.executed = Command(2.0)
    Actuate()(ctx)
    leader = backend.vehicles["p.0"]
    limits = ctx.run.plan.platoons[0].limits
    assert leader.speed_mps == pytest.approx(min(2.0, 0.1 * limits.max_accel_mps2))
    assert backend.removed == [("p.1", False)] and "p.1" not in ctx.fleet
    (removed,) = [e for e in ctx.events if e.kind is EventKind.REMOVED]
    assert removed.vehicle_id == "p.1" and "off the road" in removed.detail


def test_route_progress_removes_a_member_at_its_route_end_as_arrived(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)
    backend.vehicles["p.0"].x_m = 3000.0
    ctx.fleet.get("p.0").route_s_m = 2995.0  # type: ignore[union-attr]  # it drove there
    ObserveWorld()(ctx)
    ReadBack()(ctx)
    RouteProgress()(ctx)
    assert backend.removed == [("p.0", True)] and len(ctx.fleet) == 0
    assert ctx.events[-1].kind is EventKind.ARRIVED and ctx.arrived_total == 1


def test_safety_check_counts_a_contact_once_when_it_begins(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    backend.add_human("h", 200.0, 0.0)
    departed(ctx, backend)
    check = SafetyCheck()
    kinds = []
    for front in (125.0, 103.0, 103.5, 125.0, 103.0):  # apart, touch, still, apart, touch
        backend.vehicles["h"].x_m = front
        ObserveWorld()(ctx)
        ReadBack()(ctx)
        Footprints()(ctx)
        ctx.events = []
        check(ctx)
        kinds.append([(e.kind, e.vehicle_id, e.other_id) for e in ctx.events])
    hit = [(EventKind.COLLISION, "p.0", "h")]
    assert kinds == [[], hit, [], [], hit]


def test_safety_check_blames_the_car_whose_footprint_moved_into_the_other(write_scenario):
    """At fault is judged on how the footprints moved over the step, not on the speeds
    reported: a car SUMO places onto a member's front (its rear 7 m back from where the
    step began, its speed saying it drove on) caused the contact. Another car leaves
    the world in that step, so the two worlds' rows differ."""
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)  # p.0's front bumper at x 100
    backend.vehicles["p.0"].speed_mps = 3.0
    backend.add_human("g", 130.0, 3.0)  # the row before h's, gone after the step
    backend.add_human("h", 112.0, 3.0)
    ObserveWorld()(ctx)
    ReadBack()(ctx)
    Footprints()(ctx)
    check = SafetyCheck()
    check(ctx)
    Sense()(ctx)  # the world the step begins with
    backend.step()  # both drive on 0.3 m; then SUMO places h 7.8 m back
    backend.vehicles["h"].x_m -= 7.8  # its rear at x 100.0, p.0's front at 100.3
    del backend.vehicles["g"]
    ObserveWorld()(ctx)
    ReadBack()(ctx)
    Footprints()(ctx)
    ctx.events = []
    check(ctx)
    hits = [(e.vehicle_id, e.other_id, e.at_fault, e.detail) for e in ctx.events]
    assert hits == [("p.0", "h", "h", PLACED)]


def contacts_after_step(ctx, check: SafetyCheck) -> list[tuple[str, str, str, str]]:
    """Observe the world after a step and run the safety check on it: its contacts as
    (vehicle, other, at fault, reason)."""
    ObserveWorld()(ctx)
    ReadBack()(ctx)
    Footprints()(ctx)
    ctx.events = []
    check(ctx)
    return [(e.vehicle_id, e.other_id, e.at_fault, e.detail) for e in ctx.events]


@pytest.mark.parametrize(
    ("steps_before", "at_fault", "reason"), [(1, "h", PLACED_RECENTLY), (12, "p.0", FRONT)]
)
def test_safety_check_blames_a_car_placed_just_ahead_of_a_member(
    write_scenario, steps_before, at_fault, reason
):
    """A car SUMO places just ahead of a member, without touching it, caused the
    contact when it landed within the member's reach (what the member covers in 1 s,
    plus half the two lengths) and the member's front reaches it 0.1 s later; not when
    it landed farther and the member reaches it 1.2 s later (its front struck it)."""
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)  # p.0's front bumper at x 100
    backend.vehicles["p.0"].speed_mps = 3.0  # 0.3 m a step
    backend.add_human("h", 110.0, 0.0)  # standing, within the world's reach
    check = SafetyCheck()
    hits = []
    for step in range(steps_before + 2):
        hits += contacts_after_step(ctx, check)
        if step == steps_before + 1:  # p.0's front reaches h's rear
            break
        Sense()(ctx)  # the world the step begins with
        backend.step()
        if step == 0:  # SUMO places h, its rear 0.1 m beyond p.0's front steps_before on
            front = backend.vehicles["p.0"].x_m + 0.3 * steps_before - 0.2
            backend.vehicles["h"].x_m = front + 4.5
    assert hits == [("p.0", "h", at_fault, reason)]


def test_safety_check_blames_a_car_whose_body_sumo_swung_into_a_members_path(write_scenario):
    """Found on a race circuit (seed 44, 102.9 s): SUMO turned a car by 50 degrees in a
    step, its centre 0.96 m beyond its speed, a corner 4 m; its side landed 0.18 m ahead
    of a member creeping on, which touched it a step later. A placement is judged by
    how far the body moved (its farthest corner), not only its centre. Here the car
    stands and turns 60 degrees about its centre: the centre does not move at all."""
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)  # p.0's front bumper at x 100, 0.3 m a step
    backend.vehicles["p.0"].speed_mps = 3.0
    y0 = backend.vehicles["p.0"].y_m
    centre, yaw = (100.2, y0 + 3.0), 0.0  # beside and ahead, 1.2 m apart
    backend.add_human("h", centre[0] + 2.25, 0.0)
    backend.vehicles["h"].y_m = centre[1]
    check = SafetyCheck()
    hits = []
    for step in range(3):
        hits += contacts_after_step(ctx, check)
        if step == 0:
            assert not hits
        Sense()(ctx)  # the world the step begins with
        backend.step()
        if step == 0:  # SUMO turns h about its centre: its front-right corner 6 cm
            yaw = -math.radians(60.0)  # ahead of p.0's front, which reaches it next step
            h = backend.vehicles["h"]
            h.yaw_rad = yaw
            h.x_m, h.y_m = centre[0] + 2.25 * math.cos(yaw), centre[1] + 2.25 * math.sin(yaw)
    assert hits == [("p.0", "h", "h", PLACED_RECENTLY)]


def test_obstacles_ahead_finds_a_body_reaching_into_the_path_from_another_lane(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)  # p.0's front bumper at x 100, on the lane's centre line
    found = []
    # standing p.0 looks 10 m ahead: a car beside its lane with its rear 5 m ahead,
    # 2.0 m off the centre line (apart from the 2.2 m corridor), 1.3 m (0.2 m into
    # it), then 1.3 m off but 40 m behind; the last one comes the other way (its front
    # bumper at x 105: its body reaches to x 109.5)
    cases = ((109.5, 2.0, 0.0), (109.5, 1.3, 0.0), (60.0, 1.3, 0.0), (105.0, 1.3, np.pi))
    for x, y, yaw in cases:
        backend.vehicles["h"] = FakeVehicle(x, LANE_Y_M + y, speed_mps=3.0, yaw_rad=yaw)
        ObserveWorld()(ctx)
        ReadBack()(ctx)
        Footprints()(ctx)
        ObstaclesAhead()(ctx)
        found.append(ctx.fleet.get("p.0").obstacle_ahead)
    assert found[0] is None and found[2] is None
    ahead = found[1]
    assert ahead is not None and ahead.vehicle_id == "h"
    assert 5.0 - 0.5 <= ahead.gap_m <= 5.0  # its rear at x 105 (slices of 0.5 m)
    assert ahead.speed_mps == pytest.approx(3.0)
    assert found[3] is not None and found[3].speed_mps == 0.0  # oncoming: a standing obstacle


def test_sumos_leader_is_an_obstacle_when_its_body_reaches_nearer_than_its_gap(
    write_scenario,
):
    """SUMO's gap to its leader follows the lanes: a car standing across the lane reaches
    nearer than its lane position says (osm_spreewaldring: SUMO's gap 4.41 m, the bodies
    3.84 m apart, and the follower ran into it). The corridor check then reports it; a
    leader whose body is where SUMO's gap puts it is not repeated."""
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)  # p.0's front bumper at x 100, on the lane's centre line
    # standing across the lane, its side 5.1 m ahead of p.0's bumper
    backend.vehicles["h"] = FakeVehicle(106.0, LANE_Y_M - 2.25, yaw_rad=-np.pi / 2)
    found = []
    for sumo_gap_m in (9.0, 5.1, 5.4):
        ObserveWorld()(ctx)
        ReadBack()(ctx)
        Footprints()(ctx)
        member = ctx.fleet.get("p.0")
        member.vehicle_ahead = VehicleAhead("h", sumo_gap_m, 0.0)
        ObstaclesAhead()(ctx)
        found.append(member.obstacle_ahead)
    ahead = found[0]
    assert ahead is not None and ahead.vehicle_id == "h"
    assert 5.1 - 0.5 <= ahead.gap_m <= 5.1  # slices of 0.5 m
    assert found[1] is None and found[2] is None  # SUMO's gap is the body's (a slice on)


def test_a_car_sumo_is_to_move_across_the_path_is_an_obstacle_a_min_gap_early(
    write_scenario,
):
    """A car that SUMO moves sideways only with room behind it (a lane change it waits
    to make, a car in a junction beside its next lane) holds a member that can stop
    short of that room comfortably when it first sees it, and then until it has moved
    over: an obstacle the member's SUMO minGap before its back, standing. A member
    within that room already, or too fast to stop short of it, drives on (the car then
    moves over behind it); a nearer obstacle in the corridor stays the one reported."""
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)
    config = ctx.fleet.get("p.0").platoon.config
    min_gap, comfort = config.vehicle.min_gap_m, config.supervisor.comfort_decel_mps2
    backend.vehicles["h"] = FakeVehicle(110.0, LANE_Y_M + 3.2, speed_mps=0.0)  # beside
    stage = ObstaclesAhead()

    def ahead(waits: dict[str, tuple[str, float]], speed_mps: float) -> VehicleAhead | None:
        backend.waiting_behind = waits
        backend.vehicles["p.0"].speed_mps = speed_mps
        ObserveWorld()(ctx)
        ReadBack()(ctx)
        Footprints()(ctx)
        stage(ctx)
        return ctx.fleet.get("p.0").obstacle_ahead

    fast = 10.0
    far = min_gap + fast**2 / (2.0 * comfort) - 1.0  # a metre short of a comfortable stop
    assert ahead({}, 0.0) is None  # the car beside is not in the corridor
    assert ahead({"p.0": ("h", 10.0)}, 0.0) == VehicleAhead("h", 10.0 - min_gap, 0.0)
    assert ahead({"p.0": ("h", 1.0)}, 0.0) is None  # within the room already: drives on
    assert ahead({"p.0": ("h", far)}, fast) is None  # first seen too late to stop
    assert ahead({"p.0": ("h", 30.0)}, 0.0) is not None
    held = ahead({"p.0": ("h", far)}, fast)  # held since it was first seen: kept
    assert held == VehicleAhead("h", far - min_gap, 0.0)
    backend.vehicles["k"] = FakeVehicle(107.0, LANE_Y_M, speed_mps=0.0)  # in the path
    nearer = ahead({"p.0": ("h", 30.0)}, 0.0)
    assert nearer is not None and nearer.vehicle_id == "k"


def test_a_car_held_in_a_circle_of_right_of_way_takes_the_junction(write_scenario):
    """SUMO holds p.0 at a minor link, yielding to h; h stands too (it yields to
    someone else). After `STANDOFF_S`, once h has stood for `FOES_STILL_S`, p.0 takes
    the junction; once across (on another lane) it yields again. While h moves, or
    before the time, nothing happens."""
    backend = FakeBackend()
    ctx = context(plan(write_scenario, members=1), backend)
    departed(ctx, backend)
    member = ctx.fleet.get("p.0")
    assert member is not None
    backend.vehicles["h"] = FakeVehicle(130.0, LANE_Y_M + 20.0, speed_mps=2.0)
    backend.yields["p.0"] = ["h"]
    standoffs = Standoffs()
    taken_at = []

    def step(seconds: float) -> None:
        for _ in range(round(seconds / ctx.dt_s)):
            backend.time = round(backend.time + ctx.dt_s, 9)
            ObserveWorld()(ctx)
            member.link_ahead = LinkAhead("m", False, False, True, 1.0)
            ctx.events = []
            standoffs(ctx)
            taken_at.extend(ctx.world.time_s for e in ctx.events if e.kind is EventKind.STANDOFF)

    step(STANDOFF_S - 1.0)
    backend.vehicles["h"].standing_s = FOES_STILL_S  # before the time
    step(0.5)
    assert not taken_at
    backend.vehicles["h"].standing_s = FOES_STILL_S - 1.0  # h stopped only just now
    step(2.0)
    assert not taken_at and "p.0" not in backend.taking_right_of_way
    backend.vehicles["h"].standing_s = FOES_STILL_S
    now = backend.time
    step(1.0)
    assert backend.taking_right_of_way == {"p.0": True}
    assert taken_at == [pytest.approx(now + ctx.dt_s)]  # at once
    backend.vehicles["p.0"].lane_id = ":j_0_0"  # inside the junction: still taking it
    step(1.0)
    assert backend.taking_right_of_way == {"p.0": True}
    backend.vehicles["p.0"].lane_id = "out_0"  # across
    step(0.1)
    assert backend.taking_right_of_way == {"p.0": False} and len(taken_at) == 1


def test_sumo_reports_count_each_collision_once(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario), backend)
    reports = SumoReports()
    seen = []
    for active in ([("a", "b", "collision")], [("a", "b", "collision")], [], [("a", "b", "x")]):
        backend.collisions = active
        ctx.events = []
        reports(ctx)
        seen.append(len(ctx.events))
    assert seen == [1, 0, 0, 1]


def test_cohesion_counts_a_split_after_the_hold_and_a_reformation(write_scenario):
    backend = FakeBackend()
    laser = {"type": "route_following", "sensor": {"preset": "utm30lx"}}
    ctx = context(plan(write_scenario, follower=laser), backend)
    departed(ctx, backend)
    Predecessors()(ctx)
    cohesion = Cohesion(hold_s=1.0)
    follower = ctx.fleet.get("p.1")
    assert follower is not None and follower.predecessor_id == "p.0"
    kinds = []
    for k in range(60):
        backend.time = round(backend.time + 0.1, 9)
        ObserveWorld()(ctx)
        follower.predecessor_rays = 0 if 15 <= k < 35 else 50
        ctx.events = []
        cohesion(ctx)
        kinds += [e.kind for e in ctx.events]
    assert kinds == [EventKind.SPLIT, EventKind.REFORMATION]


def test_a_sensor_plug_in_needs_no_loop_edit(write_scenario, monkeypatch):
    monkeypatch.syspath_prepend(str(PLUGINS))
    sensors = [{"type": "perfect_radar:PerfectRadar", "name": "radar", "params": {"rate_hz": 5}}]
    backend = FakeBackend()
    role = {"type": "route_following", "sensors": sensors}
    ctx = context(plan(write_scenario, follower=role), backend)
    departed(ctx, backend)
    RouteProgress()(ctx)
    sense = Sense()
    readings = []
    for _ in range(4):
        sense(ctx)
        follower = ctx.fleet.get("p.1")
        assert follower is not None
        readings.append(follower.sensors.get("radar"))
        backend.time = round(backend.time + 0.1, 9)
        ObserveWorld()(ctx)
    assert readings[0].gap_m == pytest.approx(5.0)  # the true bumper gap to p.0
    assert readings[1] is readings[0] and readings[2] is not readings[0]  # 5 Hz, 10 Hz steps
    assert "radar" not in ctx.fleet.get("p.0").sensors  # type: ignore[union-attr]


class Collector(StepHook):
    def __init__(self) -> None:
        self.steps = 0
        self.outcome: RunOutcome | None = None
        self.frozen_objects: list[int] = []

    def on_step(self, record: Any) -> None:
        self.steps += 1
        self.frozen_objects.append(gc.get_freeze_count())

    def on_end(self, outcome: RunOutcome) -> None:
        self.outcome = outcome


def scripted_run(write_scenario) -> tuple[CoSimulation, Collector]:
    """A one-member run on the fake backend, its leader `Scripted` at 3 m/s, watched."""
    hook = Collector()
    sim = CoSimulation(plan(write_scenario, members=1, leader=SCRIPTED), FakeBackend(), [hook])
    Scripted.speed = 3.0
    return sim, hook


def test_the_loop_ends_every_hook_when_a_stage_fails(write_scenario):
    sim, hook = scripted_run(write_scenario)
    sim.step(), sim.step(), sim.step()
    Scripted.speed = RuntimeError("late failure")
    with pytest.raises(PluginError):
        sim.run()
    Scripted.speed = 5.0
    assert hook.outcome is not None and hook.outcome.status == "failed"
    assert "late failure" in hook.outcome.error
    assert hook.steps == 3  # the failing step's record never reached the hooks
    assert gc.get_freeze_count() <= INTERPRETER_FROZEN  # the loop's freeze ended with the failure


def test_the_run_leaves_its_objects_out_of_collections_while_it_steps(write_scenario):
    sim, hook = scripted_run(write_scenario)
    assert gc.get_freeze_count() <= INTERPRETER_FROZEN  # nothing but the interpreter's own
    assert sim.run().status == "complete"
    assert hook.steps == 200 and min(hook.frozen_objects) > 1000  # the plan, network, ...
    assert gc.get_freeze_count() <= INTERPRETER_FROZEN  # back in the collector's passes


def test_gridlocks_are_found_every_ten_seconds_once_per_episode(write_scenario):
    backend = FakeBackend()
    ctx = context(plan(write_scenario), backend)
    stage = Gridlocks()
    backend.standing = [("h", "WE_0", 50.0, LANE_Y_M, 400.0), ("q", "WE_0", 40.0, LANE_Y_M, 90.0)]
    for step in range(1, 301):  # 30 s: checks at 10, 20 and 30 s
        backend.time, ctx.steps = step * 0.1, step
        if step == 150:  # h moved, then stood again
            backend.standing = []
        if step == 250:
            backend.standing = [("h", "WE_0", 60.0, LANE_Y_M, 305.0)]
        stage(ctx)
    found = ctx.events
    assert [(e.kind, e.vehicle_id) for e in found] == [
        (EventKind.GRIDLOCK, "h"),
        (EventKind.GRIDLOCK, "h"),
    ]  # q stood 90 s only (below the default 300 s); h twice: two episodes
    assert [round(e.time_s, 6) for e in found] == [10.0, 30.0]
    assert found[0].detail == "lane WE_0 at (50.0, -5.2), still for 400 s"
