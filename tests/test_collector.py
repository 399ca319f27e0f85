"""The garbage collector around a run: paused while a run is built, the run's objects
left out of its passes while it steps, and left as it was found afterwards."""

from __future__ import annotations

import gc

import pytest

from platoon_sumo import collector
from platoon_sumo.collector import (
    INTERPRETER_FROZEN,
    collector_paused,
    existing_objects_frozen,
)
from platoon_sumo.runner import load_plan
from tests.helpers import REPO


@pytest.fixture(autouse=True)
def collector_restored():
    enabled = gc.isenabled()
    assert gc.get_freeze_count() <= INTERPRETER_FROZEN  # nothing frozen but its own
    yield
    gc.unfreeze()
    (gc.enable if enabled else gc.disable)()


def test_paused_while_building_and_running_again_after():
    gc.enable()
    with collector_paused():
        assert not gc.isenabled()
    assert gc.isenabled()


def test_paused_leaves_a_collector_the_caller_turned_off_off():
    gc.disable()
    with collector_paused():
        assert not gc.isenabled()
    assert not gc.isenabled()


def test_paused_runs_again_when_the_block_raises():
    gc.enable()
    with pytest.raises(RuntimeError), collector_paused():
        raise RuntimeError("failed while building")
    assert gc.isenabled()


def test_objects_made_before_the_block_are_frozen_during_it_only():
    before = [[] for _ in range(10)]  # tracked objects, alive through the block
    with existing_objects_frozen():
        frozen = gc.get_freeze_count()
        assert frozen > len(before)
        new = [[] for _ in range(10)]  # noqa: F841
        # what the block makes is collected as usual: not in the frozen generation
        assert gc.get_freeze_count() == frozen
    assert gc.get_freeze_count() <= INTERPRETER_FROZEN


def test_frozen_block_ends_its_freeze_when_it_raises():
    with pytest.raises(KeyboardInterrupt), existing_objects_frozen():
        raise KeyboardInterrupt
    assert gc.get_freeze_count() <= INTERPRETER_FROZEN


def test_the_interpreters_own_frozen_objects_do_not_stop_the_freeze(monkeypatch):
    # CPython 3.12 starts with objects of its own frozen (`INTERPRETER_FROZEN`): the
    # block still freezes, and hands everything back at its end
    gc.freeze()
    monkeypatch.setattr(collector, "INTERPRETER_FROZEN", gc.get_freeze_count())
    made_after = [[] for _ in range(10)]
    with existing_objects_frozen():
        assert gc.get_freeze_count() >= collector.INTERPRETER_FROZEN + len(made_after)
    assert gc.get_freeze_count() <= INTERPRETER_FROZEN


def test_a_freeze_of_the_caller_is_not_undone():
    gc.freeze()
    held = gc.get_freeze_count()
    with existing_objects_frozen():
        assert gc.get_freeze_count() == held
    assert gc.get_freeze_count() == held  # the caller's: still frozen after the block


def test_loading_a_plan_makes_one_collector_pass_at_most_and_leaves_it_running():
    passes: list[int] = []

    def count(phase: str, info: dict[str, int]) -> None:
        if phase == "start":
            passes.append(info["generation"])

    gc.enable()
    gc.callbacks.append(count)
    try:
        plan = load_plan(REPO / "scenarios" / "urban_platoon.yaml")
    finally:
        gc.callbacks.remove(count)
    assert plan.platoons  # the network, routes and paths were built
    # the pass the allocations owe, when the collector runs again (without the pause: 10
    # passes for this scenario, 414 for the DRT city's, three of them over every object)
    assert len(passes) <= 1
    assert gc.isenabled()
