"""Sensing: every due sensor of every platoon vehicle, batched per model and parameters.

Sensors observe the world read after the previous SUMO step (`ctx.world`), the same
world the controllers then decide on.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.errors import PluginError
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.fleet import ACCEL, SPEED, YAW, Member
from platoon_sumo.platoon import predecessor_ids
from platoon_sumo.sensors.base import SensingBatch, SensorModel
from platoon_sumo.sensors.laser import LaserScan


class Sense:
    def __init__(self) -> None:
        self._models: dict[tuple[type, Any], SensorModel] = {}
        """One instance per sensor model and parameters: the members sharing them are
        sensed in one batch."""

    def __call__(self, ctx: StepContext) -> None:
        ctx.sensed_world, ctx.sensed_footprints = ctx.world, ctx.footprints
        members = ctx.fleet.members()
        if not members:
            return
        time_s = ctx.world.time_s
        fleet = ctx.fleet
        predecessors = fleet.fixed("predecessors", predecessor_ids)  # as `Predecessors`'
        for group in fleet.fixed((self, "groups"), lambda ms: self._groups(ms, predecessors)):
            model, pairs = group.model, group.pairs
            if model.period_s - 1e-9 > ctx.dt_s:  # not due every step
                due = [
                    k
                    for k, (m, name) in enumerate(pairs)
                    if time_s - m.last_sensed_s.get(name, -np.inf) >= model.period_s - 1e-9
                ]
                if not due:
                    continue
                if len(due) < len(pairs):
                    group = group.subset(due)
                    pairs = group.pairs
            messages = _observe(model, _batch(ctx, group), group.ids, time_s)
            for (m, name), message in zip(pairs, messages, strict=True):
                m.sensors[name] = message
                m.last_sensed_s[name] = time_s
                if isinstance(message, LaserScan):
                    m.predecessor_rays = message.predecessor_rays or 0

    def _groups(
        self, members: Sequence[Member], predecessors: dict[str, str | None]
    ) -> list[_Group]:
        """The members' sensors by model and parameters, each with what stays the same
        while the same members drive (`predecessors`: each member's)."""
        pairs: dict[int, tuple[SensorModel, list[tuple[Member, str]]]] = {}
        for m in members:
            for sensor in m.plan.sensors:
                key = (sensor.model, sensor.params)
                model = self._models.get(key)
                if model is None:
                    model = self._models[key] = sensor.model(sensor.params)
                pairs.setdefault(id(model), (model, []))[1].append((m, sensor.name))
        return [_Group.of(model, group, predecessors) for model, group in pairs.values()]


@dataclass(frozen=True)
class _Group:
    """The members one sensor model senses (`pairs`: each member and its sensor's name)
    and what stays the same about them while the same members drive."""

    model: SensorModel
    pairs: list[tuple[Member, str]]
    ids: tuple[str, ...]
    rows: NDArray[np.int64]
    predecessors: list[str | None]
    platoon_ids: tuple[str, ...]
    member_index: NDArray[np.int64]

    @classmethod
    def of(
        cls,
        model: SensorModel,
        pairs: list[tuple[Member, str]],
        predecessors: dict[str, str | None],
    ) -> _Group:
        members = [m for m, _ in pairs]
        rows = np.fromiter((m.row for m in members), dtype=np.int64, count=len(members))
        index = np.array([m.index for m in members], dtype=np.int64)
        for shared in (rows, index):
            shared.flags.writeable = False
        return cls(
            model, pairs, tuple(m.id for m in members), rows,
            [predecessors.get(m.id) for m in members], tuple(m.platoon_id for m in members),
            index,
        )  # fmt: skip

    def subset(self, at: list[int]) -> _Group:
        return _Group(
            self.model, [self.pairs[k] for k in at], tuple(self.ids[k] for k in at),
            self.rows[at], [self.predecessors[k] for k in at],
            tuple(self.platoon_ids[k] for k in at), self.member_index[at],
        )  # fmt: skip


def _batch(ctx: StepContext, group: _Group) -> SensingBatch:
    """What the group's members sense now."""
    index, rows, kin = ctx.world.index, group.rows, ctx.fleet.kin
    front_x_m, front_y_m = ctx.fleet.front_bumpers(rows)
    members = [m for m, _ in group.pairs]
    return SensingBatch(
        time_s=ctx.world.time_s,
        vehicle_ids=group.ids,
        front_x_m=front_x_m,
        front_y_m=front_y_m,
        yaw_rad=kin[rows, YAW],
        speed_mps=kin[rows, SPEED],
        own_index=np.array([index.get(vid, -1) for vid in group.ids], dtype=np.int64),
        predecessor_index=np.array(
            [index.get(p, -1) if p is not None else -1 for p in group.predecessors],
            dtype=np.int64,
        ),
        vehicle_ahead=tuple(m.vehicle_ahead for m in members),
        world=ctx.world,
        footprints=ctx.footprints,
        static_segments=ctx.run.static_segments,
        rng=ctx.rng,
        platoon_ids=group.platoon_ids,
        member_index=group.member_index,
        accel_mps2=kin[rows, ACCEL],
        desired_accel_mps2=np.array([m.desired_accel_mps2 for m in members]),
    )


def _observe(
    model: SensorModel, batch: SensingBatch, ids: tuple[str, ...], time_s: float
) -> list[Any]:
    """The model's messages for the batch, one per vehicle; a plug-in's failure named."""
    name = type(model).__qualname__
    try:
        messages = list(model.observe(batch))
    except Exception as exc:
        raise PluginError(
            f"sensor {name} of vehicles {', '.join(ids[:3])} failed at "
            f"t={time_s:.2f} s: {type(exc).__name__}: {exc}"
        ) from exc
    if len(messages) != len(ids):
        raise PluginError(
            f"sensor {name} returned {len(messages)} messages "
            f"for {len(ids)} vehicles at t={time_s:.2f} s"
        )
    return messages
