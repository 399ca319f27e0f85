"""tools/speed_study.py without SUMO runs: the arc_time_s sweep's cases, scenario and
outputs (on made-up results), and its command-line checks."""

from __future__ import annotations

import importlib.util
import json
import sys

import pytest
import yaml

from tests.helpers import REPO


@pytest.fixture(scope="module")
def tool():
    spec = importlib.util.spec_from_file_location("speed_study", REPO / "tools" / "speed_study.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["speed_study"] = module  # dataclasses look their module up
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.modules.pop("speed_study", None)


def test_without_arc_times_the_cases_are_the_follower_comparison(tool):
    cases = tool.plan_cases([0.1, 0.2], ["paper_follower", "laser_follower"], 0.5)
    assert [(c.follower, c.speed_mps, c.arc_time_s) for c in cases] == [
        ("paper_follower", 0.1, None),
        ("paper_follower", 0.2, None),
        ("laser_follower", 0.1, None),
        ("laser_follower", 0.2, None),
    ]
    assert cases[0].end_s == round(20.0 + 0.5 * tool.LAP_M / 0.1, 2)


def test_arc_times_run_the_paper_follower_once_per_value_and_speed(tool):
    cases = tool.plan_cases([0.1, 0.3], ["laser_follower"], 0.25, arc_times=[1.0, 8.0])
    assert [(c.follower, c.arc_time_s, c.speed_mps) for c in cases] == [
        ("paper_follower", 1.0, 0.1),
        ("paper_follower", 1.0, 0.3),
        ("paper_follower", 8.0, 0.1),
        ("paper_follower", 8.0, 0.3),
    ]


def test_the_scenario_changes_only_arc_time_s(tool):
    base = yaml.safe_load(tool.SCENARIO.read_text())
    scenario = tool.scenario_for(tool.Case("paper_follower", 0.2, 30.0, arc_time_s=2.0), base)
    follower = scenario["platoons"][0]["follower"]
    assert follower["params"] == {**base["platoons"][0]["follower"]["params"], "arc_time_s": 2.0}
    assert scenario["platoons"][0]["leader"]["params"]["linear_mps"] == 0.2
    default = tool.scenario_for(tool.Case("paper_follower", 0.2, 30.0), base)
    assert default["platoons"][0]["follower"] == base["platoons"][0]["follower"]
    with pytest.raises(ValueError, match="paper_follower only"):
        tool.scenario_for(tool.Case("laser_follower", 0.2, 30.0, arc_time_s=2.0), base)


def _row(arc: float, speed: float, intact: bool) -> dict:
    return {
        "follower": "paper_follower",
        "arc_time_s": arc,
        "leader_speed_mps": speed,
        "simulated_s": 30.0,
        "intact": intact,
        "min_in_view_share": 1.0 if intact else 0.996,
        "lost_scans": 0 if intact else 19,
        "collisions": 0,
        "min_gap_m": 0.32,
        "lost_followers": "" if intact else "robots.4",
        "collision_events": "",
    }


def test_arc_outputs_give_the_intact_speeds_per_arc_time(tool, tmp_path):
    rows = [
        _row(2.0, 0.1, False),
        _row(2.0, 0.2, True),
        _row(4.0, 0.1, True),
        _row(4.0, 0.2, True),
        _row(4.0, 0.3, False),
    ]
    tool.write_arc_outputs(rows, tmp_path, "python tools/speed_study.py --arc-times 2 4")
    table = (tmp_path / "arc_time_study.md").read_text()
    assert "| leader speed [m/s] | `arc_time_s` 2 s | `arc_time_s` 4 s |" in table
    assert "| 0.1 | **lost** (in view 99.6%, min gap 0.32 m) | intact (in view 100%" in table
    assert "| 0.3 |  | **lost**" in table  # 2 s did not run at 0.3 m/s
    assert "| 2 | 0.5 | {0.2} | 0.2 | none (lowest speed lost) |" in table
    assert "| 4 | 0.25 | {0.1, 0.2} | 0.2 | 0.2 |" in table
    summary = json.loads((tmp_path / "arc_time_study.json").read_text())
    assert summary["highest_intact"] == {"2": 0.2, "4": 0.2}
    assert summary["range_max_m"] == 1.0
    assert (tmp_path / "arc_time_study.png").stat().st_size > 0
    assert (tmp_path / "arc_time_study.csv").exists()
    assert not (tmp_path / "speed_study.md").exists()


def test_arc_times_reject_other_followers_and_non_positive_values(tool, tmp_path, capsys):
    for argv in (
        ["--arc-times", "2", "--followers", "laser_follower"],
        ["--arc-times", "0", "4"],
        ["--replot", "--out", str(tmp_path)],  # nothing to replot
    ):
        with pytest.raises(SystemExit) as stop:
            tool.main(argv)
        assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "paper_follower only" in err
    assert "must be > 0" in err
    assert "no speed_study.json or arc_time_study.json" in err
