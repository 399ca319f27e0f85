"""The fleet's struct of arrays: every member's state is its row, whole-fleet helpers
agree with the per-member view, rows survive removals and growth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from platoon_sumo.loop.fleet import KINEMATICS, Fleet
from tests.loop.test_stages import plan


def test_members_read_and_write_their_rows(write_scenario):
    run_plan = plan(write_scenario, members=3)
    platoon = run_plan.platoons[0]
    fleet = Fleet(capacity=2)  # grows on the third member
    members = []
    for k, member_plan in enumerate(platoon.members):
        m = fleet.join(member_plan, platoon, None, None, None)  # type: ignore[arg-type]
        m.x_m, m.y_m, m.yaw_rad, m.speed_mps = 10.0 * k, -2.0, 0.3 * k, 5.0 + k
        members.append(m)
    assert len(fleet.kin) >= 3 and [m.row for m in members] == [0, 1, 2]
    assert fleet.kin.shape[1] == len(KINEMATICS)
    assert members[2].x_m == 20.0 and members[1].speed_mps == 6.0  # after the growth
    offset = platoon.config.vehicle.front_offset_m
    assert all(m.front_offset_m == offset for m in members)

    rows = fleet.rows(members)
    fx, fy = fleet.front_bumpers(rows)
    for m, x, y in zip(members, fx, fy, strict=True):
        assert (x, y) == pytest.approx(m.front_bumper(), abs=1e-12)

    fleet.set_front_poses(rows, fx + 1.0, fy, np.array([0.0, math.pi / 2, -1.0]))
    for m, x, y in zip(members, fx + 1.0, fy, strict=True):
        assert m.front_bumper() == pytest.approx((x, y), abs=1e-12)
    assert members[1].yaw_rad == pytest.approx(math.pi / 2)

    fleet.remove(members[0].id)
    assert fleet.ids() == [members[1].id, members[2].id]
    assert members[2].row == 2
    assert members[2].x_m == pytest.approx(fx[2] + 1.0 - offset * math.cos(-1.0))
    newcomer = fleet.join(platoon.members[0], platoon, None, None, None)  # type: ignore[arg-type]
    assert newcomer.row == 3 and newcomer.x_m == 0.0  # rows are never reused
