"""``step_batch`` over mixed controller classes: classes with a ``step_many`` stepped as
a group and the others one by one give the same commands, in order, as stepping every
controller on its own; a failure names the vehicle."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import pytest

from platoon_sumo.control.base import (
    Command,
    Observation,
    ObservationColumns,
    ObservationRows,
    step_batch,
)
from platoon_sumo.control.laser_follower import LaserFollower
from platoon_sumo.control.paper import PaperFollower, PaperFollowerParams, PaperLeader
from platoon_sumo.control.route_following import RouteFollowing
from platoon_sumo.control.speed_profile import SpeedProfileLeader
from platoon_sumo.errors import PluginError
from platoon_sumo.world import VehicleAhead
from tests.control.observation_log import FollowerLog, load, logs


@dataclass(frozen=True)
class CreepParams:
    speed_mps: float = 0.7


class Creep:
    """A plug-in written against ``step`` only (no ``step_many``), with state."""

    Params: ClassVar[type[CreepParams]] = CreepParams

    def __init__(self, params: CreepParams | None = None):
        self.params = params or CreepParams()
        self.steps = 0

    def reset(self) -> None:
        self.steps = 0

    def step(self, observation: Observation) -> Command:
        self.steps += 1
        return Command(self.params.speed_mps + 0.01 * self.steps, -0.1 * observation.yaw_rad)


class BatchedCreep(Creep):
    """A plug-in that steps its vehicles as one group (``step_many``)."""

    groups: ClassVar[list[int]] = []

    @classmethod
    def step_many(
        cls, controllers: list[BatchedCreep], observations: list[Observation]
    ) -> list[Command]:
        cls.groups.append(len(controllers))
        return [c.step(o) for c, o in zip(controllers, observations, strict=True)]


LOGS: list[FollowerLog] = [log for path in logs() for log in load(path)]


def _fleet() -> list[tuple[object, FollowerLog]]:
    """One controller per (class, log): interleaved so no class is contiguous."""
    city, urban, robot = (
        [log for log in LOGS if log.vehicle_id.startswith(prefix)]
        for prefix in ("west", "cars", "robots")
    )
    fleet: list[tuple[object, FollowerLog]] = []
    for k in range(2):
        fleet += [
            (RouteFollowing(city[k].params.fallback), city[k]),
            (LaserFollower(urban[k].params), urban[k]),
            (Creep(), robot[k]),
            (
                LaserFollower(dataclasses.replace(city[k].params, on_lost="route_following")),
                city[k],
            ),
            (PaperFollower(PaperFollowerParams(max_speed_mps=0.5)), robot[k]),
            (SpeedProfileLeader(), urban[k]),
            (PaperLeader(), robot[k]),
            (BatchedCreep(), city[k]),
            (RouteFollowing(robot[k].params.fallback), robot[k]),
        ]
    return fleet


def _observation(log: FollowerLog, k: int) -> Observation:
    obs = log.observations[k % len(log.observations)]
    if k % 5 == 0:  # now and then a vehicle ahead (the route followers read it)
        obs = dataclasses.replace(obs, vehicle_ahead=VehicleAhead("a", 3.0 + 0.1 * k, 1.0))
    return obs


def test_step_batch_of_mixed_classes_equals_stepping_each_controller():
    batch, single = _fleet(), _fleet()
    assert {type(c) for c, _ in batch} >= {RouteFollowing, LaserFollower, Creep, PaperLeader}
    BatchedCreep.groups.clear()
    for k in range(400):
        observations = [_observation(log, k) for _, log in batch]
        got = step_batch([c for c, _ in batch], observations)  # type: ignore[misc]
        want = [c.step(o) for (c, _), o in zip(single, observations, strict=True)]  # type: ignore[attr-defined]
        assert got == want, k
    assert BatchedCreep.groups == [2] * 400  # both, as one group, every step
    modes = {c.mode for c, _ in batch if isinstance(c, LaserFollower)}
    assert "following" in modes


def test_observations_as_columns_are_built_only_where_a_controller_reads_them():
    """The loop hands ``step_batch`` its observations as columns (``ObservationRows``):
    the commands are those of stepping each controller with its built observation, each
    observation is built at most once, and a laser follower whose batched step keeps
    following never has its built."""
    batch, single = _fleet(), _fleet()
    lasers = {k for k, (c, _) in enumerate(batch) if isinstance(c, LaserFollower)}
    laser_builds = 0
    for k in range(400):
        observations = [_observation(log, k) for _, log in batch]
        built: list[int] = []

        def build(row: int, observations: list[Observation] = observations) -> Observation:
            built.append(row)  # noqa: B023 (this step's list, read before the next)
            return observations[row]

        rows = ObservationRows(ObservationColumns.of(observations), build)
        got = step_batch([c for c, _ in batch], rows)  # type: ignore[misc]
        want = [c.step(o) for (c, _), o in zip(single, observations, strict=True)]  # type: ignore[attr-defined]
        assert got == want, k
        assert len(built) == len(set(built)), k
        laser_builds += len(lasers.intersection(built))
    assert 0 < laser_builds < 0.05 * 400 * len(lasers)  # most laser steps built nothing


@pytest.mark.parametrize("batched", [False, True])
def test_step_batch_names_the_vehicle_whose_step_failed(batched):
    log = LOGS[0]
    obs = dataclasses.replace(log.observations[10], x_m=float("nan"), vehicle_id="broken")
    good = log.observations[10]
    controllers = [RouteFollowing(log.params.fallback), RouteFollowing(log.params.fallback)]
    if batched:

        class Batched(RouteFollowing):
            @classmethod
            def step_many(cls, controllers, observations):  # type: ignore[no-untyped-def]
                return [c.step(o) for c, o in zip(controllers, observations, strict=True)]

        controllers = [Batched(log.params.fallback), Batched(log.params.fallback)]
    with pytest.raises(PluginError, match=r"broken.*non-finite"):
        step_batch(controllers, [good, obs])  # type: ignore[arg-type]
