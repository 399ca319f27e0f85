"""Every registered controller passes the same battery (plug-ins are held to it too)."""

from __future__ import annotations

import inspect
import math
import re

import libsumo
import numpy as np
import pytest

from platoon_sumo.control import CONTROLLERS
from platoon_sumo.control.base import Command, Observation, reads_link_ahead
from platoon_sumo.path import RoutePath
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import SignalAhead


class _NoSumo:
    def __getattr__(self, name: str):
        raise AssertionError(f"controllers must not call SUMO (called libsumo ...{name})")


@pytest.fixture
def no_sumo(monkeypatch):
    for domain in ("vehicle", "simulation", "lane", "edge", "trafficlight", "route", "junction"):
        monkeypatch.setattr(libsumo, domain, _NoSumo())


def observations() -> list[Observation]:
    pts = np.column_stack([np.linspace(0, 200, 401), np.zeros(401)])
    path = RoutePath.from_pieces([pts], ["e_0"], [13.89], [3.2], 0.5)
    limits = MotionLimits(15.0, 2.5, 7.5, 1.0)
    base = dict(
        dt_s=0.1,
        vehicle_id="v",
        role="leader",
        front_offset_m=3.6,
        length_m=4.5,
        width_m=1.8,
        limits=limits,
        path=path,
    )
    return [
        Observation(time_s=0.0, x_m=0.0, y_m=0.0, yaw_rad=0.0, speed_mps=0.0, **base),
        Observation(time_s=0.1, x_m=5.0, y_m=0.4, yaw_rad=0.1, speed_mps=10.0, **base),
        Observation(
            time_s=0.2,
            x_m=50.0,
            y_m=-1.0,
            yaw_rad=-0.2,
            speed_mps=13.0,
            signal=SignalAhead("t", 0, "r", 20.0),
            **base,
        ),
    ]


@pytest.mark.parametrize("name", CONTROLLERS.names())
def test_controller_contract(name, no_sumo):
    cls = CONTROLLERS.get(name)
    commands = []
    for _ in range(2):  # two fresh instances must decide identically
        ctrl = cls(cls.Params())
        ctrl.reset()
        commands.append([ctrl.step(obs) for obs in observations()])
    assert commands[0] == commands[1]
    for cmd in commands[0]:
        assert isinstance(cmd, Command)
        assert cmd.speed_mps >= 0 and not math.isnan(cmd.speed_mps)
        assert math.isfinite(cmd.yaw_rate_radps)
        assert cmd.heading_rad is None or math.isfinite(cmd.heading_rad)
    # reset really forgets: a reset instance repeats the first decisions
    ctrl.reset()
    assert [ctrl.step(obs) for obs in observations()] == commands[0]


@pytest.mark.parametrize("name", CONTROLLERS.names())
def test_a_controller_saying_it_never_reads_the_link_does_not(name):
    """`reads_link_ahead = False` spares the vehicle SUMO's link query, and its
    observations then hold no link: a controller saying so must not read it."""
    cls = CONTROLLERS.get(name)
    if reads_link_ahead(cls):
        return
    for klass in cls.__mro__:
        module = inspect.getmodule(klass)
        if module is not None and module.__name__.startswith("platoon_sumo.control."):
            source = inspect.getsource(module)
            assert not re.search(r"(?<!reads_)link_ahead", source), (name, module.__name__)
