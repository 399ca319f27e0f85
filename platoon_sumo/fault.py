"""Who caused a contact between two vehicles, from their footprints and motions at its
onset: a physical attribution (who moved into whom), not a legal one (right of way is
not judged). Used for every footprint collision the loop finds; SUMO's own collision
reports name their collider themselves.

The rules, in order (docs/metrics.md):

0. **Placed onto the other.** A vehicle whose footprint's centre, or its body at the
   contact, moved over the step farther than its reported speed covers, by more than
   `PLACED_M` and faster by more than `PLACED_MPS` (SUMO moved or turned it there; it
   did not drive there), while the other's did not, is at fault. So is, otherwise, a
   vehicle SUMO placed so (by its farthest corner's motion) at most
   `PLACED_REACTION_S` before the contact within the other's reach (what the other
   covers in that time at its speed then, plus half the two lengths), while the other
   was not: the other could not react to it (a cut-in).
1. **Sideways into the other's path.** A vehicle beside the other (`BESIDE_SHARE`)
   moving across its lane towards it faster than `SIDEWAYS_MPS` (a lane change, a
   drift, a cut-in) while the other does not is at fault. Motion across the lane is
   the change of the front's distance to the lane's centre line where that is known.
1b. **Passed too close beside.** Otherwise, of two vehicles beside each other on their
   lanes, neither moving across them faster than `SIDEWAYS_MPS`, the one driving
   faster along its lane (by more than `TIE_MPS`) is at fault: it is passing the other
   with too little room for the bodies, which on a bend swing across the lane (SUMO
   lets a car pass another inside a wide lane 0.2 m apart, and on the race circuit's
   hairpin their bodies, drawn from back to front along the lane, overlapped by 0.9 m).
2. **Front into side or rear.** Otherwise, when exactly one vehicle closes on the other
   and has the contact in the front quarter of its body, that vehicle struck the other
   (a rear-end, a car running into a crossing car's side).
3. **Closing faster.** Otherwise, the vehicle that closes on the other faster, by more
   than `TIE_MPS`, and at more than `TIE_MPS`.
4. **Swept into a standing vehicle.** Otherwise, when one vehicle moves (at least
   `TIE_MPS`) and the other stands, the mover (its body swept into the other, e.g. its
   rear swinging out in a turn); else nobody (``None``).

A vehicle closes on the other at the rate its own motion over the step, with the other
held at its footprint of the step's start, shrank the gap between them (footprints
apart) or deepened their overlap: a rigid body's motion, so a rear swinging into the
other closes on it and a front that only crept beside a swinging body does not.

A vehicle slower than `TIE_MPS` (its measured motion, else its reported speed) is never
at fault by rules 1-4: SUMO reports a stopped car's speed as rounding noise (1e-15
m/s), which must not decide.

A vehicle's motion is, where known, how its footprint moved and turned over the step
in which the contact began, not its reported speed along its yaw: SUMO's sublane model
places cars that leave a wide junction lane several metres from where the step began
(4.9 to 6.3 m in 0.1 s at 7-8.5 m/s, measured on an OpenStreetMap race circuit), and
turns cars in a tight bend by up to 50 degrees a step (a 5 m car's rear then sweeps
3 m sideways at 19 m/s); the reported speed and yaw then say the car drove along its
lane while its body landed on another car.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from shapely.geometry import Polygon

from platoon_sumo.geometry import CX, CY, LENGTH, WIDTH, YAW, penetration_depths, rectangle_corners

#: Speed towards the other vehicle's centre line that makes a sideways intrusion [m/s]
#: (a lane change in SUMO's sublane model moves at about 1 m/s; tracking a lane's centre
#: moves a few centimetres a second).
SIDEWAYS_MPS = 0.3
#: Rule 1 needs the two centres at least this share of their mean width apart across
#: the lane (at a cut-in's first contact they are nearly a full width apart; a car
#: running into another's rear a little off-centre is not beside it).
BESIDE_SHARE = 0.5
#: Closing speeds closer than this are a tie, and a vehicle slower than this stands [m/s].
TIE_MPS = 0.1
#: A contact this far forward of the body's centre (share of half the length) is on its front.
FRONT_SHARE = 0.5

#: A footprint that moved farther than its vehicle's reported speed covers in the step,
#: by more than PLACED_M [m] and faster by more than PLACED_MPS [m/s], was placed, not
#: driven: braking hard (9 m/s^2) over a step of up to 1 s leaves at most 4.5 m/s
#: between the step's mean speed and its end speed; a car SUMO moved out of a wide
#: junction lane landed 6 m from its last position at 8.5 m/s (an OpenStreetMap race
#: circuit).
PLACED_M, PLACED_MPS = 1.0, 5.0
#: A vehicle placed within the other's reach at most this long before their contact
#: caused it [s]: the other had less than a driver's reaction time (a car SUMO placed
#: 0.2 m beside a slow platoon car's front on a race circuit touched it in the next
#: step). Without SUMO's sublane model a lane change is such a placement (3.2 m
#: sideways in one step): a lane change that closes on a car within its reach is a
#: cut-in.
PLACED_REACTION_S = 1.0

PLACED = "placed onto the other (moved farther than its speed)"
PLACED_RECENTLY = "placed within the other's reach less than a reaction time before"
SIDEWAYS = "moved sideways into the other's path"
PASSING = "passed the other too close beside it"
FRONT = "front into the other's side or rear"
CLOSING = "closing faster"
SWEPT = "swept into a standing vehicle"


@dataclass(frozen=True)
class Fault:
    """The vehicle at fault (0: the first, 1: the second, None: undetermined) and why."""

    at_fault: int | None
    reason: str
    contact_x_m: float
    contact_y_m: float


def contact_fault(
    rect_a: ArrayLike,
    rect_b: ArrayLike,
    speed_a_mps: float,
    speed_b_mps: float,
    lane_yaw_a_rad: float | None = None,
    lane_yaw_b_rad: float | None = None,
    motion_a_mps: tuple[float, float] | None = None,
    motion_b_mps: tuple[float, float] | None = None,
    step_s: float = 0.1,
    turn_a_rad: float = 0.0,
    turn_b_rad: float = 0.0,
    placed_recently_a: bool = False,
    placed_recently_b: bool = False,
    across_a_mps: float | None = None,
    across_b_mps: float | None = None,
) -> Fault:
    """Attribute the contact of two overlapping rectangles ``(cx, cy, yaw, length, width)``
    whose vehicles move along their yaw at the given speeds, each on a lane running in
    direction ``lane_yaw`` where it is (None: along the vehicle, no sideways motion).
    ``motion_*_mps``, when given, is the vehicle's measured velocity (x, y) over the
    step the contact began in (its footprint centre's displacement / `step_s`), used
    instead of speed along yaw, ``turn_*_rad`` how far its footprint turned over that
    step, and ``placed_recently_*`` whether SUMO placed it (``was_placed``) within the
    other's reach at most `PLACED_REACTION_S` before. ``across_*_mps``, when given, is
    how fast the vehicle's front moved across its lane over that step (to the left +,
    from its distance to the lane's centre line), used for its sideways motion instead
    of its velocity against the lane's direction: where a lane bends, a body keeping its
    place across the lane moves its centre across the direction of the lane there."""
    rects = np.vstack([np.asarray(rect_a, dtype=np.float64), np.asarray(rect_b, dtype=np.float64)])
    corners = rectangle_corners(rects)
    overlap = Polygon(corners[0]).intersection(Polygon(corners[1]))
    if overlap.is_empty or overlap.area <= 0.0:  # only touching: between the centres
        cx, cy = 0.5 * (rects[0, CX] + rects[1, CX]), 0.5 * (rects[0, CY] + rects[1, CY])
    else:
        cx, cy = overlap.centroid.x, overlap.centroid.y
    lanes = (lane_yaw_a_rad, lane_yaw_b_rad)
    reported = (float(speed_a_mps), float(speed_b_mps))
    velocity = [
        (float(m[0]), float(m[1]))
        if m is not None
        else (v * math.cos(r[YAW]), v * math.sin(r[YAW]))
        for v, r, m in zip(
            reported,
            rects,
            (motion_a_mps, motion_b_mps),
            strict=True,
        )
    ]
    # a vehicle's speed: its measured motion's, else the speed it reports (exactly: the
    # length of its velocity along the yaw rounds 0.1 m/s to 0.09999999999999999)
    speeds = [
        math.hypot(*v) if m is not None else abs(r)
        for v, m, r in zip(velocity, (motion_a_mps, motion_b_mps), reported, strict=True)
    ]
    turns = (float(turn_a_rad), float(turn_b_rad))
    across = (across_a_mps, across_b_mps)

    def side(i: int) -> float:
        """Where the other is across vehicle i's lane (left +), 0 when more ahead or
        behind than beside (or i is not on a lane)."""
        lane = lanes[i]
        if lane is None:
            return 0.0
        nx, ny = -math.sin(lane), math.cos(lane)  # the lane's left normal
        j = 1 - i
        apart = (rects[j, CX] - rects[i, CX]) * nx + (rects[j, CY] - rects[i, CY]) * ny
        beside = BESIDE_SHARE * 0.5 * (rects[i, WIDTH] + rects[j, WIDTH])
        return apart if abs(apart) >= beside else 0.0

    def sideways(i: int) -> float:
        """Speed of vehicle i across its lane, towards the side where the other is."""
        lane, where = lanes[i], side(i)
        if lane is None or where == 0.0:
            return 0.0
        own = across[i]
        if own is None:
            own = velocity[i][0] * -math.sin(lane) + velocity[i][1] * math.cos(lane)
        return math.copysign(1.0, where) * own

    def passing() -> int | None:
        """Beside each other on their lanes, both keeping their place across them (the
        bodies met on a bend): the one driving faster along its lane, passing the other."""
        if None in lanes or None in across or 0.0 in (side(0), side(1)):
            return None
        if max(abs(a) for a in across if a is not None) > SIDEWAYS_MPS:
            return None
        along = [
            velocity[i][0] * math.cos(lane) + velocity[i][1] * math.sin(lane)
            for i, lane in enumerate(lanes)
            if lane is not None
        ]
        if abs(along[0] - along[1]) <= TIE_MPS:
            return None
        return 0 if along[0] > along[1] else 1

    # each vehicle's own motion over the step, the other held at its footprint of the
    # step's start: how fast it closed the gap between them (rigid: turns included)
    started = [_start_of_step(rects[i], velocity[i], turns[i], step_s) for i in (0, 1)]
    gap_before = _signed_gap_m(started[0], started[1])
    closing = [
        (gap_before - _signed_gap_m(rects[0], started[1])) / step_s,
        (gap_before - _signed_gap_m(started[0], rects[1])) / step_s,
    ]

    def struck_with_front(i: int) -> bool:
        c, s = math.cos(rects[i, YAW]), math.sin(rects[i, YAW])
        ahead = (cx - rects[i, CX]) * c + (cy - rects[i, CY]) * s
        return ahead >= FRONT_SHARE * 0.5 * rects[i, LENGTH] and closing[i] > TIE_MPS

    # the centre's speed, or the body's at the contact when it turned faster there
    moved = [
        max(speeds[i], _point_moved_m(rects[i], velocity[i], turns[i], step_s, cx, cy) / step_s)
        if (motion_a_mps, motion_b_mps)[i] is not None
        else speeds[i]
        for i in (0, 1)
    ]
    placed = [bool(was_placed(moved[i] * step_s, reported[i], step_s)) for i in (0, 1)]
    if placed[0] != placed[1]:
        return Fault(0 if placed[0] else 1, PLACED, cx, cy)
    recently = [placed_recently_a or placed[0], placed_recently_b or placed[1]]
    if recently[0] != recently[1]:  # (placed in this step counts as recently)
        return Fault(0 if recently[0] else 1, PLACED_RECENTLY, cx, cy)
    into = [sideways(i) > SIDEWAYS_MPS for i in (0, 1)]
    if into[0] != into[1]:
        return Fault(0 if into[0] else 1, SIDEWAYS, cx, cy)
    passer = passing()
    if passer is not None:
        return Fault(passer, PASSING, cx, cy)
    # the other must not close on it too (a head-on sideswipe: closing faster decides)
    fronts = [struck_with_front(i) and closing[1 - i] <= TIE_MPS for i in (0, 1)]
    if fronts[0] != fronts[1]:
        return Fault(0 if fronts[0] else 1, FRONT, cx, cy)
    if abs(closing[0] - closing[1]) > TIE_MPS and max(closing) > TIE_MPS:
        return Fault(0 if closing[0] > closing[1] else 1, CLOSING, cx, cy)
    moving = [abs(s) >= TIE_MPS for s in speeds]
    if moving[0] != moving[1]:
        return Fault(0 if moving[0] else 1, SWEPT, cx, cy)
    return Fault(None, "undetermined", cx, cy)


def was_placed(moved_m: ArrayLike, speed_mps: ArrayLike, step_s: float) -> NDArray[np.bool_]:
    """Did footprints that moved `moved_m` over a step of `step_s` while reporting
    `speed_mps` move farther than that speed covers, by more than `PLACED_M` and faster
    by more than `PLACED_MPS`: placed by SUMO, not driven?"""
    excess_m = np.asarray(moved_m, dtype=np.float64) - np.abs(speed_mps) * step_s
    return np.asarray((excess_m > PLACED_MPS * step_s) & (excess_m > PLACED_M))


def _start_of_step(
    rect: np.ndarray, velocity: tuple[float, float], turn_rad: float, step_s: float
) -> np.ndarray:
    """The footprint at the step's start: the centre moved back, the heading turned back."""
    start = rect.copy()
    start[CX] -= velocity[0] * step_s
    start[CY] -= velocity[1] * step_s
    start[YAW] -= turn_rad
    return start


def _signed_gap_m(rect_a: np.ndarray, rect_b: np.ndarray) -> float:
    """Distance between two footprints, or minus their penetration depth when they
    overlap [m]: it changes by at most how far either body moved."""
    depth = float(penetration_depths(rect_a, rect_b)[0])
    if depth > 0.0:
        return -depth
    corners = rectangle_corners(np.vstack([rect_a, rect_b]))
    return float(Polygon(corners[0]).distance(Polygon(corners[1])))


def _point_moved_m(
    rect: np.ndarray,
    velocity: tuple[float, float],
    turn_rad: float,
    step_s: float,
    x_m: float,
    y_m: float,
) -> float:
    """How far the point of the body now at (x, y) moved over the step [m]: the centre's
    displacement plus the point's turn about the centre (a rigid body)."""
    rx, ry = x_m - rect[CX], y_m - rect[CY]
    c, s = math.cos(turn_rad), math.sin(turn_rad)
    before_x, before_y = c * rx + s * ry, -s * rx + c * ry  # the offset turned back
    dx = velocity[0] * step_s + rx - before_x
    dy = velocity[1] * step_s + ry - before_y
    return math.hypot(dx, dy)
