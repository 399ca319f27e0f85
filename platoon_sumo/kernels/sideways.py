"""Would moving a vehicle sideways bring it into another one? (sublane actuation)"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from platoon_sumo.kernels.rectangles import rectangle_depth

#: A move counts as going deeper into a vehicle by more than this [m] (shifting past a
#: slightly turned car changes the depth by rounding's worth).
DEEPER_M = 1e-3


@njit(cache=True)
def sideways_conflicts(
    rects: np.ndarray,
    speed_mps: np.ndarray,
    yaw_rate_radps: np.ndarray,
    subjects: np.ndarray,
    shift_m: np.ndarray,
    horizon_s: float,
    margin_m: float,
    step_s: float = 0.0,
) -> np.ndarray:
    """Would moving each subject sideways bring it into another vehicle?

    Every rectangle (rows of `rects`: centre x, y, yaw, length, width) drives on at its
    speed, turning at its yaw rate (`advanced`); subject k (`subjects[k]`, a row of
    `rects`; -1: not in the world) is also shifted to its left (negative: right), by
    `shift_m[k]` at `horizon_s` and in proportion before. A conflict is another
    rectangle that the shifted subject, `margin_m` larger on every side, overlaps
    deeper than the unshifted one does, at the end of every step of `step_s` within
    the horizon and at the horizon (only there with `step_s` 0: a car passing beside
    at speed is level with the subject now and gone at the horizon's end): the
    sideways part of the move, not driving on, causes it (a car closing on the one
    ahead in its lane is the longitudinal layer's business)."""
    n = rects.shape[0]
    out = np.zeros(subjects.shape[0], dtype=np.bool_)
    ax = np.empty(n)
    ay = np.empty(n)
    ayaw = np.empty(n)
    radius = np.empty(n)
    for i in range(n):
        radius[i] = 0.5 * math.hypot(rects[i, 3], rects[i, 4])
    samples = max(1, math.ceil(horizon_s / step_s - 1e-9)) if step_s > 0.0 else 1
    for sample in range(1, samples + 1):
        time_s = min(sample * step_s, horizon_s) if step_s > 0.0 else horizon_s
        share = time_s / horizon_s if horizon_s > 0.0 else 1.0
        for i in range(n):
            ax[i], ay[i], ayaw[i] = advanced(
                rects[i, 0], rects[i, 1], rects[i, 2], speed_mps[i], yaw_rate_radps[i], time_s
            )
        for k in range(subjects.shape[0]):
            j = subjects[k]
            shift = shift_m[k] * share
            if j < 0 or shift == 0.0 or out[k]:
                continue
            out[k] = _deeper(rects, ax, ay, ayaw, radius, j, shift, margin_m)
    return out


@njit(cache=True)
def advanced(
    x_m: float, y_m: float, yaw_rad: float, speed_mps: float, yaw_rate_radps: float, time_s: float
) -> tuple[float, float, float]:
    """A point driven on for `time_s` at constant speed and yaw rate (on a circle; on a
    straight line without turning): its position and yaw. A car taking a 50 m curve at
    24 m/s is 1.5 m inside its straight-line place after 0.5 s, more than the room
    between two cars side by side in a wide lane."""
    turned = yaw_rate_radps * time_s
    if abs(turned) < 1e-9:
        step = speed_mps * time_s
        return x_m + math.cos(yaw_rad) * step, y_m + math.sin(yaw_rad) * step, yaw_rad
    radius = speed_mps / yaw_rate_radps
    yaw = yaw_rad + turned
    return (
        x_m + radius * (math.sin(yaw) - math.sin(yaw_rad)),
        y_m + radius * (math.cos(yaw_rad) - math.cos(yaw)),
        yaw,
    )


@njit(cache=True)
def _deeper(
    rects: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    ayaw: np.ndarray,
    radius: np.ndarray,
    j: int,
    shift: float,
    margin_m: float,
) -> bool:
    """Does rectangle j at (ax, ay, ayaw), `margin_m` larger and shifted `shift` to its
    left, overlap another rectangle deeper than unshifted?"""
    ca, sa = math.cos(ayaw[j]), math.sin(ayaw[j])
    hl, hw = 0.5 * rects[j, 3] + margin_m, 0.5 * rects[j, 4] + margin_m
    sx, sy = ax[j] - sa * shift, ay[j] + ca * shift
    reach = math.hypot(hl, hw)
    for i in range(rects.shape[0]):
        if i == j or math.hypot(ax[i] - sx, ay[i] - sy) > reach + radius[i]:
            continue
        cb, sb = math.cos(ayaw[i]), math.sin(ayaw[i])
        bhl, bhw = 0.5 * rects[i, 3], 0.5 * rects[i, 4]
        after = rectangle_depth(sx, sy, ca, sa, hl, hw, ax[i], ay[i], cb, sb, bhl, bhw)
        if after <= 0.0:
            continue
        before = rectangle_depth(ax[j], ay[j], ca, sa, hl, hw, ax[i], ay[i], cb, sb, bhl, bhw)
        if after > before + DEEPER_M:
            return True
    return False


@njit(cache=True)
def landing_conflicts(
    rects: np.ndarray,
    speed_mps: np.ndarray,
    yaw_rate_radps: np.ndarray,
    subjects: np.ndarray,
    landings: np.ndarray,
    landing_speed_mps: np.ndarray,
    horizon_s: float,
    margin_m: float,
    step_s: float,
) -> np.ndarray:
    """Would a vehicle put down at each landing rectangle (rows: centre x, y, yaw,
    length, width; subject k is row `subjects[k]` of `rects`, skipped) be, `margin_m`
    larger on every side, in another vehicle now or at the end of any step of `step_s`
    within `horizon_s`, every vehicle driving on at its speed and yaw rate (`advanced`;
    the landed one straight on at `landing_speed_mps[k]`)?"""
    n = rects.shape[0]
    out = np.zeros(landings.shape[0], dtype=np.bool_)
    samples = max(1, math.ceil(horizon_s / step_s - 1e-9))
    for k in range(landings.shape[0]):
        lx, ly, lyaw = landings[k, 0], landings[k, 1], landings[k, 2]
        lc, ls = math.cos(lyaw), math.sin(lyaw)
        lhl, lhw = 0.5 * landings[k, 3] + margin_m, 0.5 * landings[k, 4] + margin_m
        lv = landing_speed_mps[k]
        for i in range(n):
            if i == subjects[k]:
                continue
            v = speed_mps[i]
            hl, hw = 0.5 * rects[i, 3], 0.5 * rects[i, 4]
            near = math.hypot(lhl, lhw) + math.hypot(hl, hw) + (abs(v) + abs(lv)) * horizon_s
            if math.hypot(rects[i, 0] - lx, rects[i, 1] - ly) > near:
                continue
            for sample in range(samples + 1):
                t = min(sample * step_s, horizon_s)
                x, y, yaw = advanced(rects[i, 0], rects[i, 1], rects[i, 2], v, yaw_rate_radps[i], t)
                depth = rectangle_depth(
                    lx + lc * lv * t, ly + ls * lv * t, lc, ls, lhl, lhw,
                    x, y, math.cos(yaw), math.sin(yaw), hl, hw,
                )  # fmt: skip
                if depth > 0.0:
                    out[k] = True
                    break
            if out[k]:
                break
    return out
