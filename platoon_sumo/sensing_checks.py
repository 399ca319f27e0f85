"""Checks of a run plan's sensing against its spacing policies (validate and run warn).

A follower that keeps `standstill + time_gap * speed` behind its predecessor loses it
once that gap exceeds its laser's range (at 30 m/s and a 1.2 s time gap a car needs
38 m, beyond the UTM-30LX's 30 m, and stops in its lane), or once, on a curve, the
predecessor that far ahead lies outside the laser's field of view. Nothing in the run
would say why, so the plan is checked before it starts."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from platoon_sumo.control.base import GapPolicy
from platoon_sumo.scenario import MemberPlan, PlatoonPlan, RunPlan
from platoon_sumo.sensors.laser import LaserConfig


def laser_range_warnings(plan: RunPlan) -> list[str]:
    """One message per platoon whose laser followers' desired gap, at the fastest speed
    their vehicle, leader and route allow, lies beyond their laser's range."""
    out = []
    for i, platoon, laser, policy in _laser_followers(plan):
        if policy.time_gap_s <= 0.0:
            continue
        range_m = laser.range_max_m
        fastest = _fastest_mps(plan, platoon)
        if policy.desired_m(fastest) <= range_m:
            continue
        blind_above = (range_m - policy.standstill_m) / policy.time_gap_s
        out.append(
            f"{plan.source.path}: platoons[{i}] ('{platoon.config.id}'): its followers keep "
            f"{policy.standstill_m:g} m + {policy.time_gap_s:g} s x speed to their "
            f"predecessor, {policy.desired_m(fastest):.0f} m at {fastest:.1f} m/s (the "
            f"fastest its vehicle, leader and route allow), beyond their laser's "
            f"{range_m:g} m range (platoons[{i}].follower.sensor): above "
            f"{max(blind_above, 0.0):.1f} m/s they lose their predecessor; use a laser "
            "with a longer range (e.g. preset lidar_120m) or a shorter time_gap_s"
        )
    return out


#: Lateral acceleration the speed on a curve is assumed to respect [m/s²] (route
#: following's default `max_lateral_accel_mps2`).
CURVE_LATERAL_ACCEL_MPS2 = 2.0


def laser_view_warnings(plan: RunPlan) -> list[str]:
    """One message per platoon whose laser followers, driving along their route at its
    speeds (limits, curves, the fastest their vehicle and leader allow), would see their
    predecessor at its desired gap outside their laser's field of view: the bearing from
    the front bumper to the point that far ahead along the route, against the route's
    heading, at the worst place of the route."""
    out = []
    for i, platoon, laser, policy in _laser_followers(plan):
        half_fov = min(-laser.angle_min_rad, laser.angle_max_rad)
        if half_fov >= math.pi / 2:
            continue  # a predecessor ahead along any road stays in a 180 deg view
        cfg = platoon.config.vehicle
        path = plan.network.route_path(
            platoon.edges, spacing_m=0.5, first_lane=platoon.depart_lane, vclass=cfg.vclass
        )
        kappa = path.curvature_1pm(2.0 * cfg.length_m)
        speed = np.minimum(
            path.speed_limit_mps * (cfg.sumo_speed_factor or 1.2),
            np.sqrt(CURVE_LATERAL_ACCEL_MPS2 / np.maximum(kappa, 1e-9)),
        )
        speed = np.minimum(speed, _fastest_mps(plan, platoon))
        gap = policy.standstill_m + policy.time_gap_s * speed
        s = path.s_m
        ahead = np.searchsorted(s, s + gap)
        inside = ahead < len(s)
        if not inside.any():
            continue
        idx = np.flatnonzero(inside)
        d = path.xy_m[ahead[idx]] - path.xy_m[idx]
        tangent = path.xy_m[np.minimum(idx + 1, len(s) - 1)] - path.xy_m[np.maximum(idx - 1, 0)]
        bearing = np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(tangent[:, 1], tangent[:, 0])
        bearing = np.abs((bearing + math.pi) % (2 * math.pi) - math.pi)
        worst = int(np.argmax(bearing))
        if bearing[worst] <= half_fov:
            continue
        at = int(idx[worst])
        out.append(
            f"{plan.source.path}: platoons[{i}] ('{platoon.config.id}'): at {s[at]:.0f} m "
            f"along its route (lane {path.lane_ids[path.lane_index[at]]}) its followers "
            f"would see their predecessor, {gap[at]:.1f} m ahead at {speed[at]:.1f} m/s, "
            f"{math.degrees(bearing[worst]):.0f} deg off their heading, outside their "
            f"laser's +-{math.degrees(half_fov):.0f} deg field of view "
            f"(platoons[{i}].follower.sensor): they may lose it there; use a laser with a "
            "wider field of view or a shorter gap"
        )
    return out


def _laser_followers(plan: RunPlan) -> Iterator[tuple[int, PlatoonPlan, LaserConfig, GapPolicy]]:
    """(index, platoon, laser, spacing policy) of each platoon whose followers have a
    laser and report a spacing policy (the first follower stands for all: they share
    their role's configuration)."""
    for i, platoon in enumerate(plan.platoons):
        follower = next((m for m in platoon.members if m.index > 0), None)
        if follower is None or follower.laser is None:
            continue
        policy = _gap_policy(follower)
        if policy is not None:
            yield i, platoon, follower.laser, policy


def _gap_policy(member: MemberPlan) -> GapPolicy | None:
    """The spacing policy the member's controller reports, if it has one."""
    try:
        controller = member.controller_cls(member.controller_params)
    except Exception:  # a plug-in that cannot be built here is checked when the run starts
        return None
    policy = getattr(controller, "gap_policy", None)
    return policy if isinstance(policy, GapPolicy) else None


def _fastest_mps(plan: RunPlan, platoon: PlatoonPlan) -> float:
    """The vehicle's top speed, capped by the leader's cruise speed (when it has one) and
    by the route's fastest lane times the vehicle's SUMO speed factor (1.2 when drawn:
    SUMO's default spread, two deviations)."""
    config = platoon.config
    factor = config.vehicle.sumo_speed_factor or 1.2
    cruise = getattr(platoon.members[0].controller_params, "cruise_speed_mps", None)
    limits = [config.vehicle.max_speed_mps, plan.network.max_lane_speed_mps(platoon.edges) * factor]
    if isinstance(cruise, (int, float)) and math.isfinite(cruise):
        limits.append(float(cruise))
    return min(limits)
