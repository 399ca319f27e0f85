"""Checks of a run plan's sensing against its spacing policies (validate and run warn).

A follower that keeps `standstill + time_gap * speed` behind its predecessor loses it
once that gap exceeds its laser's range: at 30 m/s and a 1.2 s time gap a car needs
38 m, beyond the UTM-30LX's 30 m, and stops in its lane. Nothing in the run would say
why, so the plan is checked before it starts."""

from __future__ import annotations

import math

from platoon_sumo.control.base import GapPolicy
from platoon_sumo.scenario import MemberPlan, PlatoonPlan, RunPlan


def laser_range_warnings(plan: RunPlan) -> list[str]:
    """One message per platoon whose laser followers' desired gap, at the fastest speed
    their vehicle, leader and route allow, lies beyond their laser's range."""
    out = []
    for i, platoon in enumerate(plan.platoons):
        follower = next((m for m in platoon.members if m.index > 0), None)
        if follower is None or follower.laser is None:
            continue
        policy = _gap_policy(follower)
        if policy is None or policy.time_gap_s <= 0.0:
            continue
        range_m = follower.laser.range_max_m
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
