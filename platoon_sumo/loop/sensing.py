"""Sensing: every due sensor of every platoon vehicle, batched per model and parameters.

Sensors observe the world read after the previous SUMO step (`ctx.world`), the same
world the controllers then decide on.
"""

from __future__ import annotations

from typing import Any

import numpy as np

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
        self._model_of: dict[int, SensorModel] = {}
        """By the plan's sensor object (it lives as long as the run): hashing the frozen
        parameters for every member and step cost more than the lookup."""

    def __call__(self, ctx: StepContext) -> None:
        ctx.sensed_world, ctx.sensed_footprints = ctx.world, ctx.footprints
        members = list(ctx.fleet)
        if not members:
            return
        time_s = ctx.world.time_s
        due: dict[int, tuple[SensorModel, list[tuple[Member, str]]]] = {}
        model_of = self._model_of
        for m in members:
            for sensor in m.plan.sensors:
                model = model_of.get(id(sensor))
                if model is None:
                    key = (sensor.model, sensor.params)
                    model = self._models.get(key)
                    if model is None:
                        model = self._models[key] = sensor.model(sensor.params)
                    model_of[id(sensor)] = model
                last = m.last_sensed_s.get(sensor.name, -np.inf)
                if time_s - last >= model.period_s - 1e-9:
                    due.setdefault(id(model), (model, []))[1].append((m, sensor.name))
        if not due:
            return
        index = ctx.world.index
        predecessors = predecessor_ids(members)
        for model, group in due.values():
            ids = tuple(m.id for m, _ in group)
            rows = ctx.fleet.rows([m for m, _ in group])
            front_x_m, front_y_m = ctx.fleet.front_bumpers(rows)
            pred = [predecessors.get(m.id) for m, _ in group]
            batch = SensingBatch(
                time_s=time_s,
                vehicle_ids=ids,
                front_x_m=front_x_m,
                front_y_m=front_y_m,
                yaw_rad=ctx.fleet.kin[rows, YAW],
                speed_mps=ctx.fleet.kin[rows, SPEED],
                own_index=np.array([index.get(vid, -1) for vid in ids], dtype=np.int64),
                predecessor_index=np.array(
                    [index.get(p, -1) if p is not None else -1 for p in pred], dtype=np.int64
                ),
                vehicle_ahead=tuple(m.vehicle_ahead for m, _ in group),
                world=ctx.world,
                footprints=ctx.footprints,
                static_segments=ctx.run.static_segments,
                rng=ctx.rng,
                platoon_ids=tuple(m.platoon_id for m, _ in group),
                member_index=np.array([m.index for m, _ in group], dtype=np.int64),
                accel_mps2=ctx.fleet.kin[rows, ACCEL],
                desired_accel_mps2=np.array([m.desired_accel_mps2 for m, _ in group]),
            )
            try:
                messages = list(model.observe(batch))
            except Exception as exc:
                name = type(model).__qualname__
                raise PluginError(
                    f"sensor {name} of vehicles {', '.join(ids[:3])} failed at "
                    f"t={time_s:.2f} s: {type(exc).__name__}: {exc}"
                ) from exc
            if len(messages) != len(group):
                raise PluginError(
                    f"sensor {type(model).__qualname__} returned {len(messages)} messages "
                    f"for {len(group)} vehicles at t={time_s:.2f} s"
                )
            for (m, name), message in zip(group, messages, strict=True):
                m.sensors[name] = message
                m.last_sensed_s[name] = time_s
                if isinstance(message, LaserScan):
                    m.predecessor_rays = message.predecessor_rays or 0
