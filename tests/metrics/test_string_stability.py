"""Issue acceptance: the string-stability metric separates a string-stable follower
setting from an unstable one on the disturbance scenario (shortened runs)."""

from __future__ import annotations

import json

import pytest

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

END_S = 75.0  # 30 s warm-up + 4.5 periods of the 10 s sinusoid


@pytest.fixture(scope="module")
def gains(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict]:
    out = {}
    for setting in ("stable", "unstable"):
        scenario = REPO / "scenarios" / f"disturbance_{setting}.yaml"
        folder = tmp_path_factory.mktemp(setting)
        run(load_plan(scenario, end_s=END_S), out_dir=folder)
        summary = json.loads((folder / "summary.json").read_text())
        out[setting] = summary["platoons"][setting]
    return out


def test_accel_l2_gain_orders_stable_below_one_below_unstable(gains):
    stable, unstable = gains["stable"], gains["unstable"]
    assert stable["max_accel_l2_gain"] < 1.0 < unstable["max_accel_l2_gain"]
    assert stable["string_stable"] is True and unstable["string_stable"] is False
    # the peak spacing errors grow along the unstable platoon, shrink along the stable one
    assert stable["max_spacing_error_peak_ratio"] < 1.0 < unstable["max_spacing_error_peak_ratio"]
    for g in (stable, unstable):
        assert g["collisions"] == 0
        assert g["intact_share"] == 1.0
