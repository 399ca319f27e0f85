"""Who is at fault in a contact (platoon_sumo.fault): the typical crashes, and the
attribution's invariances (who caused a crash does not depend on the coordinates or on
which vehicle is named first)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from platoon_sumo.fault import (
    CLOSING,
    FRONT,
    PASSING,
    PLACED,
    PLACED_RECENTLY,
    SIDEWAYS,
    SWEPT,
    contact_fault,
)
from platoon_sumo.geometry import penetration_depths
from platoon_sumo.loop.relations import _lane_yaw
from platoon_sumo.sumo.network import Network
from tests.helpers import REPO

L, W = 4.5, 1.8


def car(x: float, y: float, yaw: float = 0.0) -> tuple[float, float, float, float, float]:
    return (x, y, yaw, L, W)


def test_rear_end_is_the_follower():
    leader, follower = car(0.0, 0.0), car(-4.3, 0.0)  # follower's front in the leader's rear
    fault = contact_fault(leader, follower, 2.0, 9.0)
    assert (fault.at_fault, fault.reason) == (1, FRONT)


def test_rear_end_into_a_standing_car_is_the_mover():
    standing, mover = car(0.0, 0.0), car(-4.3, 0.1)
    assert contact_fault(standing, mover, 0.0, 5.0).at_fault == 1
    assert contact_fault(mover, standing, 5.0, 0.0).at_fault == 0


def test_cut_in_is_the_lane_changer_even_when_struck_from_behind():
    # the cutter is ahead and to the left, heading 6 deg right into the other's lane; the
    # straight car's front touches its rear corner
    straight = car(0.0, 0.0)
    cutter = car(4.0, 1.6, -math.radians(6.0))
    fault = contact_fault(straight, cutter, 12.0, 12.0, 0.0, 0.0)  # both lanes run east
    assert (fault.at_fault, fault.reason) == (1, SIDEWAYS)
    # without the lanes' direction it is the car whose front touched
    assert contact_fault(straight, cutter, 12.0, 12.0).at_fault == 0


def test_a_body_keeping_its_place_across_a_bending_lane_does_not_move_sideways():
    """Found on a race circuit (seed 44, 427.8 s): a platoon car and a SUMO car side by
    side in a 10 m lane, both at a fixed place across it, took a bend; the platoon car's
    centre moved 0.18 rad off the direction of the lane segment it was on, 0.5 m/s
    towards the other, and it was blamed for a sideways move it never made. The speed
    across the lane comes from the front's distance to the lane's centre line."""
    inner = car(0.0, 0.0, 0.2)
    outer = car(-0.5, -1.75, 0.0)  # beside-right, corners touching
    motion = (2.9 * math.cos(-0.18), 2.9 * math.sin(-0.18))  # right of the lane's direction
    args = (inner, outer, 2.9, 3.0, 0.0, 0.0, motion, (3.0, 0.0))
    assert contact_fault(*args).reason == SIDEWAYS  # against the lane's direction
    kept = contact_fault(*args, across_a_mps=0.0, across_b_mps=0.0)
    assert (kept.at_fault, kept.reason) == (1, PASSING)  # the faster, passing
    drifting = contact_fault(*args, across_a_mps=-0.5, across_b_mps=0.0)
    assert (drifting.at_fault, drifting.reason) == (0, SIDEWAYS)


def test_bodies_meeting_beside_each_other_on_a_bend_are_the_passing_cars():
    """Race circuit, seed 44, 428-431 s: a SUMO car passed a platoon car 0.2 m beside it
    in the 10 m lane through a hairpin, both at a fixed place across the lane; their
    bodies, turned differently, overlapped by up to 0.9 m. The faster is passing."""
    slow, fast = car(0.0, 0.0, 0.3), car(0.3, -1.8, 0.05)
    lanes = (0.0, 0.0)
    motion_slow, motion_fast = (5.0, 0.0), (5.6, 0.0)

    def judge(v_slow: float, v_fast: float, across_fast: float):
        return contact_fault(
            slow, fast, v_slow, v_fast, *lanes, (v_slow, 0.0), (v_fast, 0.0),
            across_a_mps=0.0, across_b_mps=across_fast,
        )  # fmt: skip

    assert (judge(5.0, 5.6, 0.0).at_fault, judge(5.0, 5.6, 0.0).reason) == (1, PASSING)
    assert judge(5.6, 5.0, 0.0).at_fault == 0  # the other way round
    assert judge(5.0, 5.05, 0.0).reason != PASSING  # as fast: a tie, the later rules
    drifting = judge(5.0, 5.6, 0.5)  # the passing car moves over, to the left: rule 1
    assert drifting.reason == SIDEWAYS
    swapped = contact_fault(
        fast, slow, 5.6, 5.0, *lanes, motion_fast, motion_slow, across_a_mps=0.0,
        across_b_mps=0.0,
    )  # fmt: skip
    assert (swapped.at_fault, swapped.reason) == (0, PASSING)


def test_side_swipe_is_the_drifting_car():
    a = car(0.0, 0.0)
    b = car(0.5, 1.7, -math.radians(4.0))  # beside, drifting right into a
    assert contact_fault(a, b, 10.0, 10.0, 0.0, 0.0).at_fault == 1


def test_crossing_car_hit_in_its_side_blames_the_striker():
    crossing = car(0.0, 0.0, math.pi / 2)  # northbound, its side towards the west
    striker = car(-3.0, 0.0, 0.0)  # eastbound, front at x=-0.75 inside the crossing car
    fault = contact_fault(crossing, striker, 6.0, 8.0, math.pi / 2, 0.0)
    assert (fault.at_fault, fault.reason) == (1, FRONT)


def test_two_standing_cars_are_nobodys_fault():
    fault = contact_fault(car(0.0, 0.0), car(-4.3, 0.0), 0.0, 0.0)
    assert fault.at_fault is None


def test_head_on_blames_the_faster():
    a, b = car(0.0, 0.0), car(4.3, 0.2, math.pi)
    fault = contact_fault(a, b, 3.0, 10.0)
    assert (fault.at_fault, fault.reason) == (1, CLOSING)


def _moved(rect, dx, dy, turn):
    c, s = math.cos(turn), math.sin(turn)
    x, y, yaw, length, width = rect
    return (c * x - s * y + dx, s * x + c * y + dy, yaw + turn, length, width)


scenes = st.tuples(
    st.floats(-3.0, 3.0), st.floats(-2.0, 2.0), st.floats(-math.pi, math.pi),
    st.floats(0.0, 15.0), st.floats(0.0, 15.0),
    st.sampled_from([None, 0.0, 0.3, math.pi / 2, math.pi]),
)  # fmt: skip


@settings(max_examples=200, deadline=None)
@given(scene=scenes, dx=st.floats(-1e3, 1e3), dy=st.floats(-1e3, 1e3), turn=st.floats(-4, 4))
def test_attribution_is_invariant_to_naming_order_and_rigid_motion(scene, dx, dy, turn):
    bx, by, byaw, va, vb, lane_b = scene
    a, b = car(0.0, 0.0), car(bx, by, byaw)
    # a contact's first step: the bodies overlap, a little
    assume(math.hypot(bx, by) > 0.5 and penetration_depths([a], [b])[0] > 0.01)
    base = contact_fault(a, b, va, vb, 0.0, lane_b)
    swapped = contact_fault(b, a, vb, va, lane_b, 0.0)
    assert swapped.at_fault == (None if base.at_fault is None else 1 - base.at_fault)
    lane_b_moved = None if lane_b is None else lane_b + turn
    moved = contact_fault(
        _moved(a, dx, dy, turn), _moved(b, dx, dy, turn), va, vb, turn, lane_b_moved
    )
    assert moved.at_fault == base.at_fault or _near_threshold(a, b, va, vb, lane_b)
    # the contact point moves with the scene
    c, s = math.cos(turn), math.sin(turn)
    expected = (c * base.contact_x_m - s * base.contact_y_m + dx,
                s * base.contact_x_m + c * base.contact_y_m + dy)  # fmt: skip
    assert np.allclose((moved.contact_x_m, moved.contact_y_m), expected, atol=1e-6)


@settings(max_examples=300, deadline=None)
@given(scene=scenes, creep=st.sampled_from([0.0, 1e-15, 4.2e-15, 1e-6, 0.05, 0.099]))
@example(scene=(0.0, 0.0, 1.9, 0.0, 0.1, None), creep=0.0)  # 0.1 m/s along yaw 1.9 rad
def test_a_standing_vehicle_is_never_at_fault(scene, creep):
    """Standing includes SUMO's stopped speeds (rounding noise, 1e-15 m/s) and a creep
    below 0.1 m/s; and when the other moves, it is the one at fault."""
    bx, by, byaw, _, vb, lane_b = scene
    assume(penetration_depths([car(0.0, 0.0)], [car(bx, by, byaw)])[0] > 0.01)
    fault = contact_fault(car(0.0, 0.0), car(bx, by, byaw), creep, vb, 0.0, lane_b)
    assert fault.at_fault != 0
    if vb >= 0.1:
        assert fault.at_fault == 1


def test_a_car_whose_rear_swings_into_a_stopped_car_is_at_fault():
    """Found on a race circuit: a car stopped in a junction (SUMO speed 4e-15 m/s) was
    blamed for 'closing faster' on every car whose rear corner, moving away from the
    contact, swept its front while turning past it."""
    stopped = car(0.0, 0.0)
    # ahead, heading away to the left at 40 deg: its rear-left corner in the stopped
    # car's front-right corner, the contact behind its centre, so it moves away from it
    passing = car(4.3, 0.06, math.radians(40.0))
    assert penetration_depths([stopped], [passing])[0] > 0.01
    fault = contact_fault(stopped, passing, 4.2e-15, 6.0)
    assert (fault.at_fault, fault.reason) == (1, SWEPT)
    assert contact_fault(passing, stopped, 6.0, 4.2e-15).at_fault == 0


def _near_threshold(a, b, va, vb, lane_b) -> bool:
    """Rounding after a rigid motion may tip a value lying on a rule's threshold."""
    base = contact_fault(a, b, va, vb, 0.0, lane_b).at_fault
    nudged = [(a, b, va + e, vb) for e in (1e-6, -1e-6)] + [
        (a, b, va, vb + e) for e in (1e-6, -1e-6)
    ]
    nudged += [
        (a, (b[0] + ex, b[1] + ey, *b[2:]), va, vb) for ex in (-1e-6, 1e-6) for ey in (-1e-6, 1e-6)
    ]
    return any(contact_fault(*n, 0.0, lane_b).at_fault != base for n in nudged)


def test_a_rear_end_a_little_off_centre_is_the_follower_even_with_heading_noise():
    # at 20-30 m/s a heading 1.2 deg off the lane is 0.4 m/s sideways: the leader, 0.3 m
    # off the follower's line, is ahead of it, not beside it
    leader, follower = car(4.4, 0.3, -0.021), car(0.0, 0.0)
    fault = contact_fault(follower, leader, 30.0, 20.0, 0.0, 0.0)
    assert (fault.at_fault, fault.reason) == (0, FRONT)


def test_a_contact_at_a_cars_centre_gives_the_same_answer_in_either_order():
    """Deep overlap with the contact's centroid on one car's centre (found by hypothesis):
    the direction to the contact is rounding noise and must not decide."""
    a, b = car(0.0, 0.0), car(0.59375, 0.0, 2.0)
    base = contact_fault(a, b, 0.0, 1.0, 0.0, None)
    swapped = contact_fault(b, a, 1.0, 0.0, None, 0.0)
    assert swapped.at_fault == (None if base.at_fault is None else 1 - base.at_fault)


def test_a_car_placed_onto_another_is_at_fault_by_its_measured_motion():
    """Found on a race circuit: SUMO's sublane model placed a car leaving a wide junction
    lane 6 m from where the step began, its rear onto a slow platoon car's front, while
    its speed and yaw said it drove on along its lane."""
    slow, placed = car(0.0, 0.0), car(4.3, 0.3)
    # reported: both drive east, the slow car's front in the other's rear
    assert contact_fault(slow, placed, 1.2, 8.5).at_fault == 0
    # measured: the placed car came from 6 m ahead and to the left within the step
    fault = contact_fault(slow, placed, 1.2, 8.5, motion_a_mps=(1.2, 0.0),
                          motion_b_mps=(-40.0, -45.0))  # fmt: skip
    assert (fault.at_fault, fault.reason) == (1, PLACED)
    # landing ahead of the slow car, moving away from the contact: still the placed one
    fault = contact_fault(slow, placed, 1.2, 8.5, motion_a_mps=(1.2, 0.0),
                          motion_b_mps=(62.7, -1.9))  # fmt: skip
    assert (fault.at_fault, fault.reason) == (1, PLACED)
    # driven there: 4.5 m/s over its end speed after braking at 9 m/s^2 over a 1 s step,
    # or moving 0.5 m beyond its speed in a 0.05 s step (10 m/s more, but under 1 m)
    # (13 m in a 1 s step: it came from behind the slow car's front and closed faster;
    # 0.9 m in 0.05 s: it was already there, and the slow car's front struck it)
    for motion_b, step_s, at_fault in (((13.0, 0.0), 1.0, 1), ((18.5, 0.0), 0.05, 0)):
        fault = contact_fault(slow, placed, 1.2, 8.5, None, None, (1.2, 0.0), motion_b, step_s)
        assert fault.reason not in (PLACED, PLACED_RECENTLY)
        assert fault.at_fault == at_fault


def test_a_car_turned_onto_another_faster_than_it_drives_is_at_fault():
    """Found on a race circuit (seed 42, 316.2 s): SUMO turned a car in a hairpin by 34
    degrees in a 0.1 s step at 19.3 m/s, its rear sweeping about 3 m sideways onto the
    front of a platoon car at 2.2 m/s (in a run of a change not kept, c7cbf6c); the
    footprint's centre moved at 25 m/s, the body at the contact at 36.6 m/s."""
    slow = (4.670, 3.095, 0.889, 4.5, 1.8)
    swung = (3.281, 5.884, 1.851, 5.0, 1.8)
    motions = dict(motion_a_mps=(1.362, 1.694), motion_b_mps=(16.18, 19.06))
    # its centre alone moved under 1 m farther than its speed covers: not placed; and
    # the slow car, whose own motion closed on it at about 2 m/s, is not blamed either
    fault = contact_fault(slow, swung, 2.16, 19.34, **motions, turn_a_rad=0.028)
    assert fault.reason not in (PLACED, PLACED_RECENTLY) and fault.at_fault != 0
    fault = contact_fault(slow, swung, 2.16, 19.34, **motions, turn_a_rad=0.028, turn_b_rad=0.59)
    assert (fault.at_fault, fault.reason) == (1, PLACED)
    # a turn a car can make (0.5 rad/s) does not place it
    fault = contact_fault(slow, swung, 2.16, 19.34, **motions, turn_a_rad=0.028, turn_b_rad=0.05)
    assert fault.reason != PLACED


def test_a_car_whose_body_swings_onto_a_creeping_cars_front_is_at_fault():
    """Found on a race circuit (seed 42, 443.8 s, sublane): a SUMO car turning inside a
    junction moved its centre 0.3 m sideways and turned 4 degrees in a step, its rear
    corner onto the front of a platoon car creeping on at 1.1 m/s. The platoon car's
    own motion over the step did not bring it closer (0.108 m apart before, 0.109 m with
    the other held where it was); it was blamed while the rules read the centres'
    velocities towards the contact."""
    creeping_was, creeping = car(276.191, 387.756, -4.179), car(276.102, 387.916, -4.175)
    swinging_was, swinging = (
        (272.253, 389.353, -3.892, 5.0, 1.8),
        (272.485, 389.558, -3.82, 5.0, 1.8),
    )
    motion = [((b[0] - a[0]) / 0.1, (b[1] - a[1]) / 0.1) for a, b in
              ((creeping_was, creeping), (swinging_was, swinging))]  # fmt: skip
    turn = [b[2] - a[2] for a, b in ((creeping_was, creeping), (swinging_was, swinging))]
    assert penetration_depths([creeping], [swinging])[0] > 0.0
    assert penetration_depths([creeping_was], [swinging_was])[0] < 0.0
    fault = contact_fault(creeping, swinging, 1.105, 7.05, -4.175, None, *motion, 0.1, *turn)
    assert fault.at_fault == 1
    swapped = contact_fault(swinging, creeping, 7.05, 1.105, None, -4.175, motion[1],
                            motion[0], 0.1, turn[1], turn[0])  # fmt: skip
    assert swapped.at_fault == 0


def test_a_car_sideswiping_an_oncoming_one_at_speed_is_at_fault():
    """Found on a race circuit (seed 45, 157.4 s): a SUMO car at 55.5 m/s on a ramp
    netconvert invented over the road came at a platoon car following at 5.3 m/s, 27
    degrees off head-on, and swiped its front corner with its side just behind its own
    front quarter. Both closed on the other (its own motion: 38 m/s, the platoon
    car's 5 m/s); the platoon car's front was the only front at the contact, and rule
    2 blamed it while the other closed on it too."""
    was = [(267.323, 208.057, -2.606, 4.5, 1.8), (261.888, 202.431, 1.019, 5.0, 1.8)]
    now = [(266.873, 207.78, -2.602, 4.5, 1.8), (264.444, 206.583, 1.019, 5.0, 1.8)]
    motion = [((b[0] - a[0]) / 0.1, (b[1] - a[1]) / 0.1) for a, b in zip(was, now, strict=True)]
    turn = [b[2] - a[2] for a, b in zip(was, now, strict=True)]
    fault = contact_fault(*now, 5.28, 55.5, None, None, *motion, 0.1, *turn)
    assert (fault.at_fault, fault.reason) == (1, CLOSING)


def test_a_car_placed_less_than_a_reaction_time_before_the_contact_is_at_fault():
    """Found on a race circuit (seed 42, 118.6 s): SUMO placed a car 2.6 m in a step at
    4.1 m/s to 0.2 m beside a platoon car's front, which touched it a step later."""
    slow, placed = car(0.0, 0.0), car(4.3, 0.3)  # the slow car's front in its rear
    moving = dict(motion_a_mps=(1.3, 0.0), motion_b_mps=(3.6, 0.0))
    assert contact_fault(slow, placed, 1.3, 3.6, **moving).reason == FRONT
    fault = contact_fault(slow, placed, 1.3, 3.6, **moving, placed_recently_b=True)
    assert (fault.at_fault, fault.reason) == (1, PLACED_RECENTLY)
    swapped = contact_fault(placed, slow, 3.6, 1.3, placed_recently_a=True)
    assert (swapped.at_fault, swapped.reason) == (0, PLACED_RECENTLY)
    # both placed: the other rules decide
    both = contact_fault(slow, placed, 1.3, 3.6, placed_recently_a=True, placed_recently_b=True)
    assert (both.at_fault, both.reason) == (0, FRONT)
    # both placed in this very step (a tie for rule 0), one of them also flagged as
    # placed recently (the safety stage notes this step's placements too): still a tie
    jumped = dict(motion_a_mps=(40.0, 0.0), motion_b_mps=(40.0, 0.0))
    tie = contact_fault(slow, placed, 1.3, 3.6, **jumped, placed_recently_b=True)
    assert tie.reason not in (PLACED, PLACED_RECENTLY)


motions = st.tuples(st.floats(-20.0, 20.0), st.floats(-20.0, 20.0))


@settings(max_examples=300, deadline=None)
@given(scene=scenes, motion_a=motions, motion_b=motions)
def test_attribution_by_measured_motion_is_invariant_to_naming_order(scene, motion_a, motion_b):
    bx, by, byaw, va, vb, lane_b = scene
    a, b = car(0.0, 0.0), car(bx, by, byaw)
    assume(math.hypot(bx, by) > 0.5 and penetration_depths([a], [b])[0] > 0.01)
    base = contact_fault(a, b, va, vb, 0.0, lane_b, motion_a, motion_b)
    swapped = contact_fault(b, a, vb, va, lane_b, 0.0, motion_b, motion_a)
    assert swapped.at_fault == (None if base.at_fault is None else 1 - base.at_fault)


@settings(max_examples=300, deadline=None)
@given(scene=scenes, motion_b=motions, creep=st.floats(0.0, 0.099))
def test_a_vehicle_whose_footprint_stands_is_never_at_fault(scene, motion_b, creep):
    """Measured: a footprint moving slower than 0.1 m/s (whatever speed it reports,
    here 5 m/s) does not cause a contact, unless SUMO placed it."""
    bx, by, byaw, _, vb, lane_b = scene
    assume(penetration_depths([car(0.0, 0.0)], [car(bx, by, byaw)])[0] > 0.01)
    fault = contact_fault(car(0.0, 0.0), car(bx, by, byaw), 5.0, vb, 0.0, lane_b,
                          (creep, 0.0), motion_b)  # fmt: skip
    assert fault.at_fault != 0


@settings(max_examples=200, deadline=None)
@given(scene=scenes)
def test_measured_motion_along_the_yaw_gives_the_reported_speeds_answer(scene):
    bx, by, byaw, va, vb, lane_b = scene
    a, b = car(0.0, 0.0), car(bx, by, byaw)
    assume(penetration_depths([a], [b])[0] > 0.01)
    motion_b = (vb * math.cos(byaw), vb * math.sin(byaw))
    with_motion = contact_fault(a, b, va, vb, 0.0, lane_b, (va, 0.0), motion_b)
    assert with_motion.at_fault == contact_fault(a, b, va, vb, 0.0, lane_b).at_fault


def test_the_sideways_rule_waits_until_the_whole_body_is_on_the_lane():
    """Found on a race circuit: a car turning out of a junction, its front on the next
    edge, heads along the turn, up to 140 degrees off the lane it enters on a ramp
    netconvert invented; its motion across that lane is the turn, not a lane change
    (the rule is off in junctions). On the lane as SUMO counts it: the front at least
    a vehicle length into it."""
    net = Network(REPO / "networks" / "straight" / "straight.net.xml")  # WE_0: x 0..3000
    assert net.lane_frame("WE_0", -1.0, -5.0) == pytest.approx((0.0, 0.0, 0.25))  # clipped
    assert net.lane_frame("WE_0", 1200.0, -6.0) == pytest.approx((0.0, 1200.0, -0.75))

    def body(front_x_m: float, heading_deg: float) -> np.ndarray:
        yaw = math.radians(heading_deg)  # the body behind the front bumper, any heading
        return np.array([front_x_m - 0.5 * L * math.cos(yaw), -5.25 - 0.5 * L * math.sin(yaw),
                         yaw, L, W])  # fmt: skip

    for heading in (0.0, 30.0, 80.0, 100.0, 140.0, -140.0):
        assert _lane_yaw(net, "WE_0", body(3.0, heading)) is None  # front 3 m in
    assert _lane_yaw(net, "WE_0", body(4.6, 0.0)) == 0.0
    assert _lane_yaw(net, "WE_0", body(50.0, 20.0)) == 0.0  # a lane change: the lane's
    assert _lane_yaw(net, ":junction_0_0", body(50.0, 0.0)) is None
