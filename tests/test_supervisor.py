"""The supervisor lowers a controller's speed for lights, minor links, lane changes and
vehicles too close ahead, and names what it enforced."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.control.base import Command, Observation, Telemetry
from platoon_sumo.path import RoutePath
from platoon_sumo.supervisor import (
    EMERGENCY,
    MERGE,
    SIGNAL,
    YIELD,
    SupervisorConfig,
    config_rows,
    supervise,
    supervise_many,
)
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import LaneChangeAhead, LinkAhead, SignalAhead, VehicleAhead
from tests import reference_supervisor as reference

PATH = RoutePath.from_pieces([np.array([[0.0, 0.0], [500.0, 0.0]])], ["e_0"], [14.0], [3.2], 0.5)


def obs(**situation) -> Observation:
    return Observation(
        time_s=0.0, dt_s=0.1, vehicle_id="v", role="follower", x_m=0.0, y_m=0.0, yaw_rad=0.0,
        speed_mps=10.0, front_offset_m=3.6, length_m=4.5, width_m=1.8,
        limits=MotionLimits(15.0, 2.5, 7.5, 1.0), path=PATH, **situation,
    )  # fmt: skip


CMD = Command(speed_mps=12.0, yaw_rate_radps=0.05)


def test_free_road_passes_the_command_unchanged():
    assert supervise(SupervisorConfig(), obs(), CMD) == (CMD, "")


@pytest.mark.parametrize(
    ("situation", "state"),
    [
        ({"signal": SignalAhead("t", 0, "r", 15.0)}, SIGNAL),
        ({"link_ahead": LinkAhead("m", False, False, True, 15.0)}, YIELD),
        ({"lane_change": LaneChangeAhead(15.0, clear=False)}, MERGE),
        ({"vehicle_ahead": VehicleAhead("x", 3.0, 0.0)}, EMERGENCY),
    ],
)
def test_each_rule_lowers_the_speed_and_says_why(situation, state):
    executed, enforced = supervise(SupervisorConfig(), obs(**situation), CMD)
    assert enforced == state
    assert 0.0 <= executed.speed_mps < 10.0  # below the current speed: it brakes
    assert executed.yaw_rate_radps == CMD.yaw_rate_radps  # never steers


@pytest.mark.parametrize(
    "situation",
    [
        {"signal": SignalAhead("t", 0, "G", 15.0)},
        {"link_ahead": LinkAhead("M", True, True, False, 15.0)},
        {"lane_change": LaneChangeAhead(15.0, clear=True)},
        {"vehicle_ahead": VehicleAhead("x", 80.0, 12.0)},
    ],
)
def test_harmless_situations_do_not_intervene(situation):
    assert supervise(SupervisorConfig(), obs(**situation), CMD) == (CMD, "")


def test_switched_off_rules_do_not_act():
    config = SupervisorConfig(signals=False, emergency_braking=False)
    red_and_close = obs(signal=SignalAhead("t", 0, "r", 15.0),
                        vehicle_ahead=VehicleAhead("x", 3.0, 0.0))  # fmt: skip
    assert supervise(config, red_and_close, CMD) == (CMD, "")


def _maybe(strategy):
    return st.one_of(st.none(), strategy)


_metres = st.floats(-5.0, 120.0, allow_nan=False)
_speeds = st.floats(0.0, 25.0, allow_nan=False)
_ahead = st.builds(VehicleAhead, st.just("x"), _metres, _speeds)
_member = st.fixed_dictionaries({
    "config": st.builds(
        SupervisorConfig, st.booleans(), st.floats(0.5, 6.0), st.floats(1.0, 8.0),
        st.floats(0.0, 2.0), st.booleans(), st.booleans(), st.booleans(), st.floats(0.0, 3.0),
    ),
    "command": st.builds(
        Command, st.floats(-1.0, 30.0, allow_nan=False),
        telemetry=_maybe(st.builds(Telemetry, desired_accel_mps2=_maybe(st.floats(-9.0, 3.0)))),
    ),
    "speed": _speeds,
    "limits": st.builds(MotionLimits, st.floats(5.0, 40.0), st.floats(0.5, 4.0),
                        st.floats(2.0, 9.0), st.floats(0.2, 1.5)),
    "signal": _maybe(st.builds(SignalAhead, st.just("t"), st.just(0),
                               st.sampled_from("rRyGgus"), _metres)),
    "link": _maybe(st.builds(LinkAhead, st.sampled_from("mM="), st.booleans(), st.booleans(),
                             st.booleans(), _metres)),
    "change": _maybe(st.builds(LaneChangeAhead, _metres, st.booleans(), _maybe(_ahead))),
    "vehicle_ahead": _maybe(_ahead),
    "obstacle_ahead": _maybe(_ahead),
    "sumo_drives": st.booleans(),
})  # fmt: skip


@settings(max_examples=300, deadline=None)
@given(st.lists(_member, min_size=1, max_size=8), st.sampled_from([0.05, 0.1, 0.5]))
def test_the_batch_is_the_one_vehicle_check_bit_for_bit(members, dt_s):
    """Every member of a batch gets what the supervisor's check of it alone gave before
    it ran as one compiled pass (`reference_supervisor`): the executed command, the
    state and the desired acceleration, to the last bit."""
    executed, enforced, accels = supervise_many(
        config_rows([m["config"] for m in members], [m["limits"] for m in members],
                    [m["sumo_drives"] for m in members]),
        [m["command"] for m in members], np.array([m["speed"] for m in members]), dt_s,
        [m["signal"] for m in members], [m["link"] for m in members],
        [m["change"] for m in members], [m["vehicle_ahead"] for m in members],
        [m["obstacle_ahead"] for m in members],
    )  # fmt: skip
    for m, run, state, accel in zip(members, executed, enforced, accels, strict=True):
        expected = reference.supervise_fields(
            m["config"], m["command"], m["speed"], dt_s, m["limits"], m["signal"], m["link"],
            m["change"], m["vehicle_ahead"], m["obstacle_ahead"], m["sumo_drives"],
        )  # fmt: skip
        assert (run, state) == expected[:2]
        assert np.float64(run.speed_mps).tobytes() == np.float64(expected[0].speed_mps).tobytes()
        assert np.float64(accel).tobytes() == np.float64(expected[2]).tobytes()
