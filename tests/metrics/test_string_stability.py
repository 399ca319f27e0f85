"""Issue 13 acceptance on the disturbance scenarios (shortened runs): the verdict tells a
string-stable tuning from an unstable one by the control law alone, and says so when the
platoon saturated or split instead of reporting it stable or unstable."""

from __future__ import annotations

import json
from typing import Any

import pytest
import yaml

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

END_S = 90.0  # 30 s warm-up + 6 periods of the 10 s sinusoid
#: The former "unstable" tuning: 10 m + 0.2 s, k_gap 1.0, +-3 m/s. Its followers drive at
#: their acceleration limit on 7 to 20 % of the steps (and its first follower's safe-speed
#: cap binds on about half, unseen in the tables): saturation, not the control law.
SATURATING = {"standstill_gap_m": 10.0, "time_gap_s": 0.2, "k_gap_1ps2": 1.0, "k_rate_1ps": 0.3}
#: The stable tuning with an 18 m laser: the followers depart 20 m behind their
#: predecessors, never see them and stay put (no `split` event: never linked). The former
#: metrics said lost_scans 0 and string_stable true, with an acceleration gain of 0.
SHORT_LASER = {"range_max_m": 18.0}


def scenario(setting: str, tmp: Any, follower: dict | None = None, laser: dict | None = None,
             amplitude: float | None = None) -> Any:  # fmt: skip
    """A disturbance scenario, with its follower, laser or leader amplitude changed."""
    data = yaml.safe_load((REPO / "scenarios" / f"disturbance_{setting}.yaml").read_text())
    data["network"]["net_file"] = str(REPO / "networks" / "straight" / "straight.net.xml")
    platoon = data["platoons"][0]
    platoon["follower"]["params"].update(follower or {})
    platoon["follower"]["sensor"]["overrides"] = laser or {}
    if amplitude is not None:
        platoon["leader"]["params"]["amplitude_mps"] = amplitude
    path = tmp / "scenario.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    cases = {
        "stable": ("stable", {}),
        "unstable": ("unstable", {}),
        "saturated": ("unstable", dict(follower=SATURATING, amplitude=3.0)),
        "split": ("stable", dict(laser=SHORT_LASER)),
    }
    out = {}
    for name, (setting, changes) in cases.items():
        tmp = tmp_path_factory.mktemp(name)
        folder = run(load_plan(scenario(setting, tmp, **changes), end_s=END_S), out_dir=tmp / "out")
        out[name] = json.loads((folder.directory / "summary.json").read_text())
    return out


def platoon(summary: dict[str, Any]) -> dict[str, Any]:
    (p,) = summary["platoons"].values()
    return p


@pytest.mark.slow
def test_stable_and_unstable_tunings_by_their_frequency_response(runs):
    stable, unstable = platoon(runs["stable"]), platoon(runs["unstable"])
    assert stable["string_stability_verdict"] == "stable" and stable["string_stable"] is True
    assert unstable["string_stability_verdict"] == "unstable"
    assert unstable["string_stable"] is False
    for p in (stable, unstable):  # the gains measure the control law: nothing saturated
        assert p["max_saturated_share"] == 0.0
        assert p["intact_share"] == 1.0 and p["collisions"] == 0
        assert p["frequency_response"] == "sinusoid"
        assert p["max_frequency_gain_hz"] == pytest.approx(0.1, rel=0.01)
    # the linear model of the spacing loop with the cars' 0.1 s actuator lag gives 0.82
    # and 1.58 at 0.1 Hz; the laser follower's tracking lag adds a little
    assert 0.8 < stable["max_frequency_gain"] < 0.9
    assert 1.5 < unstable["max_frequency_gain"] < 1.7
    for setting, bound in (("stable", 0.9), ("unstable", 1.4)):
        followers = runs[setting]["string_stability"][setting]["followers"]
        assert len(followers) == 4
        for f in followers.values():  # every member damps, or amplifies, alike
            assert (f["frequency_gain"] < bound) == (setting == "stable")
    assert stable["max_spacing_error_peak_ratio"] < 1.0 < unstable["max_spacing_error_peak_ratio"]


def test_a_saturated_platoon_is_not_judged(runs):
    p = platoon(runs["saturated"])
    assert p["max_saturated_share"] > 0.05
    assert p["string_stable"] is None and p["string_stability_verdict"] == "saturated"


def test_a_split_platoon_is_not_string_stable(runs):
    summary = runs["split"]
    p = platoon(summary)
    assert p["string_stable"] is None and p["string_stability_verdict"] == "split"
    assert p["intact_share"] < 1.0
    lost = [f for f in summary["followers"]["stable"].values() if f["in_view_share"] == 0.0]
    assert lost, "no follower lost its predecessor for the whole window"
    for f in lost:  # never in view in the window: every scan lost (it was 0 before)
        assert f["lost_scans"] > 0
    assert p["max_accel_l2_gain"] == 0.0  # they never moved
