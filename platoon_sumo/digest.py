"""The lines a finished run prints: the numbers that matter and what to type next.

A pure function of `summary.json`, so what the terminal says is what the file says
(collisions of platoon vehicles and among human drivers both, never one for the other).
"""

from __future__ import annotations

import math
import shlex
from pathlib import Path
from typing import Any


def run_digest(summary: dict[str, Any], results: Path, scenario: Path) -> str:
    """A few lines: the run, platoon safety and traffic rules, the followers' sensing
    and spacing, the results folder and the next commands."""
    s = summary
    pv = s["platoon_vehicles"]
    humans_only = s["sumo_collisions"] - s["sumo_collisions_with_platoons"]
    lines = [
        f"{s['scenario']}: {s['simulated_s']:.0f} s simulated in {s['wall_clock_s']:.1f} s "
        f"({s['real_time_factor']}x real time)",
        f"  platoon vehicles: {pv['arrived']}/{pv['planned']} arrived"
        + (f", {pv['still_running']} still driving at the end" if pv["still_running"] else "")
        + f"; {s['collisions']} collisions ({s['collisions_platoon_at_fault']} caused by a "
        f"platoon vehicle), {s['red_light_violations']} red-light violations, "
        f"{s['emergency_brakings']} emergency brakings",
        f"  human traffic: {humans_only} collisions among human drivers, {s['teleports']} "
        f"teleports, {s['gridlocks']} gridlocked vehicles",
    ]
    followers = [
        (vid, m) for platoon in s.get("followers", {}).values() for vid, m in platoon.items()
    ]
    if followers:
        lines.append("  followers: " + _followers_line(followers))
    quoted = shlex.quote(str(results))
    lines += [
        f"results: {results}",
        "next:",
        f"  platoon-sumo report {quoted}    # figures and report.md",
        f"  platoon-sumo animate {quoted}   # a video of the platoons and a laser",
        f"  platoon-sumo run {shlex.quote(str(scenario))} --gui    # watch it live in sumo-gui",
    ]
    return "\n".join(lines)


def _followers_line(followers: list[tuple[str, dict[str, Any]]]) -> str:
    """Predecessor in view and spacing error: the mean over followers and the worst one."""
    parts = []
    in_view = [(m["in_view_share"], vid) for vid, m in followers if _number(m["in_view_share"])]
    if in_view:
        mean = sum(v for v, _ in in_view) / len(in_view)
        worst, who = min(in_view)
        parts.append(
            f"predecessor in view {100 * mean:.1f} % of steps (lowest {100 * worst:.1f} %, {who})"
        )
    errors = [
        (m["rms_spacing_error_m"], vid) for vid, m in followers if _number(m["rms_spacing_error_m"])
    ]
    if errors:
        mean = sum(e for e, _ in errors) / len(errors)
        worst, who = max(errors)
        parts.append(f"RMS spacing error {mean:.2f} m (largest {worst:.2f} m, {who})")
    gaps = [(m["min_gap_m"], vid) for vid, m in followers if _number(m["min_gap_m"])]
    if gaps:
        gap, who = min(gaps)
        parts.append(f"closest gap {gap:.2f} m ({who})")
    return "; ".join(parts) or f"{len(followers)} followers, none with a predecessor in the run"


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)
