"""The fleet's struct of arrays: every member's state is its row, whole-fleet helpers
agree with the per-member view, rows survive removals and growth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from platoon_sumo.control import Command
from platoon_sumo.loop.context import vehicle_columns
from platoon_sumo.loop.fleet import KINEMATICS, Fleet
from platoon_sumo.path import RoutePath
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


def test_a_steps_columns_hold_each_members_own_values(write_scenario):
    """`VehicleColumns` (what recorders read) and the records made from it carry, for
    every member in the fleet's order, exactly what the member itself says."""
    run_plan = plan(write_scenario, members=3)
    platoon = run_plan.platoons[0]
    path = RoutePath.from_pieces(
        [np.array([[0.0, 0.0], [50.0, 0.0]]), np.array([[50.0, 0.0], [90.0, 10.0]])],
        ["a_0", "b_0"], [13.9, 8.0], [3.2, 2.9], 0.5,
    )  # fmt: skip
    fleet = Fleet()
    members = [fleet.join(mp, platoon, None, None, path) for mp in platoon.members]  # type: ignore[arg-type]
    for k, m in enumerate(members):
        m.x_m, m.y_m, m.yaw_rad, m.speed_mps, m.accel_mps2 = 20.0 * k, 0.1 * k, 0.2 * k, 7.0 + k, -k
        m.route_s_m, m.lateral_offset_m = 35.0 * k, 0.05 * k
        m.command = Command(3.0 + k, heading_rad=0.1 * k if k else None)
        m.predecessor_id = members[k - 1].id if k else None
        m.gap_to_predecessor_m = 4.0 + k if k else None
        m.predecessor_rays = 12 * k if k else None
        m.sensors = {"laser": f"scan {k}"}
        m.supervisor_state = "emergency" if k == 2 else ""
    fleet.remove(members[1].id)  # the columns follow the fleet's order after a removal
    present = [members[0], members[2]]
    columns = vehicle_columns(fleet)
    assert len(columns) == 2 and columns.id == tuple(m.id for m in present)
    for record, m in zip(columns.records(), present, strict=True):
        assert (record.front_x_m, record.front_y_m) == m.front_bumper()
        assert record.lane_width_m == path.lane_width_near(m.route_s_m)
        assert record.lane_width_m == (2.9 if m.route_s_m > 50.0 else 3.2)
        assert (record.x_m, record.y_m, record.yaw_rad, record.speed_mps, record.accel_mps2) == (
            m.x_m, m.y_m, m.yaw_rad, m.speed_mps, m.accel_mps2,
        )  # fmt: skip
        assert (record.route_s_m, record.lateral_offset_m) == (m.route_s_m, m.lateral_offset_m)
        assert record.command is m.command and record.supervisor_state == m.supervisor_state
        assert (record.predecessor_id, record.gap_to_predecessor_m, record.predecessor_rays) == (
            m.predecessor_id, m.gap_to_predecessor_m, m.predecessor_rays,
        )  # fmt: skip
        assert record.sensors == m.sensors and record.sensors is not m.sensors  # a copy
        assert record.length_m == platoon.config.vehicle.length_m
        assert (record.id, record.platoon_id, record.member_index, record.role) == (
            m.id, m.platoon_id, m.index, m.plan.role,
        )  # fmt: skip
        assert all(type(value) is float for value in record[4:15])
    assert vehicle_columns(Fleet()).records() == ()


def test_what_is_fixed_for_the_members_is_made_again_once_one_joins_or_leaves(write_scenario):
    """`Fleet.fixed` hands the stages the same value while the same members drive, and a
    new one for the members there are once a member joins or leaves; `rows` of
    `members()` is its kept, read-only array."""
    run_plan = plan(write_scenario, members=3)
    platoon = run_plan.platoons[0]
    fleet = Fleet()
    built: list[tuple[str, ...]] = []

    def ids(members) -> tuple[str, ...]:
        built.append(tuple(m.id for m in members))
        return built[-1]

    first = fleet.join(platoon.members[0], platoon, None, None, None)  # type: ignore[arg-type]
    assert fleet.fixed("ids", ids) == (first.id,)
    assert fleet.fixed("ids", ids) == (first.id,) and len(built) == 1  # kept
    second = fleet.join(platoon.members[1], platoon, None, None, None)  # type: ignore[arg-type]
    assert fleet.fixed("ids", ids) == (first.id, second.id) and len(built) == 2
    rows = fleet.rows(fleet.members())
    assert rows.tolist() == [0, 1] and not rows.flags.writeable
    assert fleet.rows(fleet.members()) is rows
    assert fleet.rows([second]).tolist() == [1] and fleet.rows([second]).flags.writeable
    fleet.remove(first.id)
    assert fleet.fixed("ids", ids) == (second.id,) and len(built) == 3
    assert fleet.rows(fleet.members()).tolist() == [1]
    assert list(fleet) == [second]
