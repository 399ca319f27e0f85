"""`frozen_from_dict` makes the same instances as the dataclasses' own `__init__`."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from platoon_sumo.control.base import Command, GapPolicy, Telemetry
from platoon_sumo.frozen import frozen_from_dict
from platoon_sumo.sensors.laser import LaserConfig, LaserScan


def test_same_instance_as_init() -> None:
    telemetry = Telemetry("following", 3.5, GapPolicy(2.5, 1.0), None)
    values = {"speed_mps": 4.0, "yaw_rate_radps": -0.1, "heading_rad": None,
              "lane_change": 1, "telemetry": telemetry, "keep_lane": True}  # fmt: skip
    fast, slow = frozen_from_dict(Command, dict(values)), Command(**values)
    assert fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
    assert dataclasses.asdict(fast) == dataclasses.asdict(slow)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.speed_mps = 1.0  # type: ignore[misc]


def test_laser_scan_unchecked_matches_from_ranges() -> None:
    config = LaserConfig(
        angle_min_rad=-1.0, angle_max_rad=1.0, samples=21, range_min_m=0.1, range_max_m=30.0
    )
    ranges = np.linspace(1.0, 2.0, config.samples)
    fast = LaserScan.unchecked(config, ranges, 1.0, 2.0, 0.5, 3.0, None, 4)
    slow = LaserScan.from_ranges(config, ranges, (1.0, 2.0), 0.5, 3.0, None, 4)
    for f in dataclasses.fields(LaserScan):
        a, b = getattr(fast, f.name), getattr(slow, f.name)
        assert a is b or a == b, f.name
    assert fast.ranges is ranges


def test_every_field_is_needed() -> None:
    with pytest.raises(TypeError, match=r"missing \['keep_lane'\], unknown \['keep'\]"):
        frozen_from_dict(Command, {"speed_mps": 1.0, "yaw_rate_radps": 0.0, "heading_rad": None,
                                   "lane_change": 0, "telemetry": None, "keep": False})  # fmt: skip


def test_refuses_a_class_that_checks_itself() -> None:
    with pytest.raises(TypeError, match="__post_init__"):
        frozen_from_dict(LaserConfig, {})
