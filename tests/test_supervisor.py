"""The supervisor lowers a controller's speed for lights, minor links, lane changes and
vehicles too close ahead, and names what it enforced."""

from __future__ import annotations

import numpy as np
import pytest

from platoon_sumo.control.base import Command, Observation
from platoon_sumo.path import RoutePath
from platoon_sumo.supervisor import EMERGENCY, MERGE, SIGNAL, YIELD, SupervisorConfig, supervise
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import LaneChangeAhead, LinkAhead, SignalAhead, VehicleAhead

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
