"""The laser follower's fused step (``kernels.following``, one kernel call per step while
it follows) against its own Python path, the oracle: with the fused step switched off
the same observations give the same commands, telemetry, tracks, trails and tracker
state, bit for bit, step by step (recorded closed-loop runs, parameter variants, scan
outages, a trail buffer that fills up), and a non-finite input raises the same error."""

from __future__ import annotations

import collections
import dataclasses
import math
from typing import Any

import numpy as np
import pytest

import platoon_sumo.control.laser_follower as laser_follower_module
from platoon_sumo.control.base import Observation
from platoon_sumo.control.laser_follower import LaserFollower, LaserFollowerParams
from platoon_sumo.kernels.following import FOLLOWED, LOST
from tests.control.observation_log import FollowerLog, load, logs
from tests.control.test_laser_follower_equivalence import VARIANTS as EQUIVALENCE_VARIANTS

LOGS = {path.name.removesuffix(".obs.xz"): path for path in logs()}


def python_only(params: LaserFollowerParams) -> LaserFollower:
    follower = LaserFollower(params)
    follower._fused_step = lambda obs: (False, None)  # type: ignore[method-assign]
    return follower


def state(f: LaserFollower) -> tuple[Any, ...]:
    """What a follower keeps between steps (and reports)."""
    t = f.tracker
    cand = t.last_candidate
    return (
        f.mode, f._route_s, f._fallback._s_m, f._mount, f._blocked, f._in_view,
        f._outside_since, f._measured_gap_m, f.track, f.trail.tobytes(), f._trail_last,
        t.active, t.hits, t.missed, t.last_hit_s, t.time_s, t.x.tobytes(),
        t.state_array.tobytes(), t.position_variance, t._velocity_variance,
        None if cand is None else (cand.x_m, cand.y_m, cand.points.tobytes()),
    )  # fmt: skip


@pytest.fixture
def statuses(monkeypatch: pytest.MonkeyPatch) -> collections.Counter[int]:
    """How the fused kernel's calls ended (FOLLOWED, LOST, ...)."""
    counts: collections.Counter[int] = collections.Counter()
    kernel = laser_follower_module.following_step_kernel

    def counted(*args: Any) -> Any:
        out = kernel(*args)
        counts[int(out[0])] += 1
        return out

    monkeypatch.setattr(laser_follower_module, "following_step_kernel", counted)
    return counts


def replay_both(log: FollowerLog, params: LaserFollowerParams) -> None:
    fused, oracle = LaserFollower(params), python_only(params)
    for k, obs in enumerate(log.observations):
        got, want = fused.step(obs), oracle.step(obs)
        where = f"{log.vehicle_id} step {k} t={obs.time_s:.2f}"
        assert got == want, where
        assert state(fused) == state(oracle), where


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(LOGS))
def test_recorded_runs_step_identically_fused(name, statuses):
    for log in load(LOGS[name]):
        replay_both(log, log.params)
    assert statuses[FOLLOWED] > 0.8 * sum(statuses.values())


# the equivalence test's variants, and a trail that outgrows its buffer
VARIANTS = {
    **EQUIVALENCE_VARIANTS,
    "long_trail": {"max_trail_points": 5000, "trail_spacing_m": 0.05},
}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_parameter_variants_step_identically_fused(variant, statuses):
    """Other modes, blocked stops, trails cut short or growing past their buffer,
    tracks dropped at a narrow corridor's exit."""
    log = load(LOGS["urban_platoon"])[0]
    log = dataclasses.replace(log, observations=log.observations[:400])
    replay_both(log, dataclasses.replace(log.params, **VARIANTS[variant]))
    if variant == "no_corridor":  # the fused step needs the route corridor
        assert not statuses
        return
    assert statuses[FOLLOWED] > 200
    if variant in ("fixed_corridor", "tight_gate"):
        assert statuses[LOST] > 0  # the kernel's own loss paths are exercised


def test_scan_outages_step_identically_fused(statuses):
    """Scans that see nothing for 2.5 s: the track is lost inside the kernel, the
    Python path stops, a new track starts and is followed again."""
    log = load(LOGS["urban_platoon"])[0]

    def blank(obs: Observation) -> Observation:
        assert obs.scan is not None
        empty = np.full_like(obs.scan.ranges, np.inf)
        return dataclasses.replace(obs, scan=dataclasses.replace(obs.scan, ranges=empty))

    observations = [blank(o) if 100 <= k < 125 else o for k, o in enumerate(log.observations)]
    replay_both(dataclasses.replace(log, observations=observations[:300]), log.params)
    assert statuses[LOST] > 0 and statuses[FOLLOWED] > 200


def test_a_non_finite_length_raises_what_the_python_path_raises():
    log = load(LOGS["urban_platoon"])[0]
    fused, oracle = LaserFollower(log.params), python_only(log.params)
    for obs in log.observations[:30]:
        fused.step(obs)
        oracle.step(obs)
    assert fused.mode == "following"
    bad = dataclasses.replace(log.observations[30], length_m=math.nan)
    with pytest.raises(ValueError) as want:
        oracle.step(bad)
    with pytest.raises(ValueError) as got:
        fused.step(bad)
    assert str(got.value) == str(want.value)
