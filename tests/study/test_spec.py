"""Study files: values, ranges, groups, key paths, seeds and their errors (no SUMO)."""

from __future__ import annotations

import pytest
import yaml

from platoon_sumo.errors import ScenarioError
from platoon_sumo.study.expand import expand, repetition_seed, scenario_for, write_scenarios
from platoon_sumo.study.spec import load_study
from tests.helpers import REPO
from tests.study.conftest import write_study


def test_grid_ranges_and_seeds(tmp_path):
    study = load_study(write_study(tmp_path, parameters={
        "platoons[0].follower.params.time_gap_s": {"from": 0.5, "to": 1.5, "step": 0.25},
        "traffic.flows[0].vehs_per_hour": [300, 600],
    }, repetitions=3, seed=5))  # fmt: skip
    assert study.values["platoons[0].follower.params.time_gap_s"] == (0.5, 0.75, 1.0, 1.25, 1.5)
    runs = expand(study)
    assert len(runs) == 5 * 2 * 3 and len({r.run_id for r in runs}) == 30
    assert {r.seed for r in runs} == {repetition_seed(5, r) for r in range(3)}
    data = scenario_for(study, runs[-1])
    assert data["platoons"][0]["follower"]["params"]["time_gap_s"] == 1.5
    assert data["traffic"]["flows"][0]["vehs_per_hour"] == 600
    assert data["simulation"]["seed"] == runs[-1].seed and data["simulation"]["end_s"] == 20.0
    assert data["network"]["net_file"].startswith("/")


def test_zip_and_every_element(tmp_path):
    study = load_study(write_study(tmp_path, combine="zip", repetitions=1, parameters={
        "platoons[*].leader.params.cruise_speed_mps": [8.0, 9.0],
        "platoons[0].members": [2, 4],
    }))  # fmt: skip
    runs = expand(study)
    assert [dict(r.values) for r in runs] == [
        {"platoons[*].leader.params.cruise_speed_mps": 8.0, "platoons[0].members": 2},
        {"platoons[*].leader.params.cruise_speed_mps": 9.0, "platoons[0].members": 4},
    ]


def test_a_group_sets_several_keys_and_names_its_level(tmp_path):
    study = load_study(write_study(tmp_path, repetitions=1, parameters={
        "follower": {
            "acc": {"platoons[0].follower.type": "acc",
                    "platoons[0].follower.params": {"time_gap_s": 1.2}},
            "laser": {"platoons[0].follower.type": "laser_follower"},
        },
        "platoons[0].leader.params.cruise_speed_mps": [8.0],
    }))  # fmt: skip
    runs = expand(study)
    assert [r.values["follower"] for r in runs] == ["acc", "laser"]
    acc = scenario_for(study, runs[0])["platoons"][0]["follower"]
    assert acc["type"] == "acc" and acc["params"] == {"time_gap_s": 1.2}
    laser = scenario_for(study, runs[1])["platoons"][0]["follower"]
    assert laser["type"] == "laser_follower" and laser["params"] == {"time_gap_s": 1.0}


@pytest.mark.parametrize(
    ("changes", "key", "words"),
    [
        ({"repetition": 2}, "repetition", "did you mean 'repetitions'"),
        ({"metrics": ["platoon.x"]}, "metrics[0]", "did you mean 'platoons'"),
        ({"metrics": ["vehicles.x:median"]}, "metrics[0]", "unknown reducer"),
        ({"metrics": []}, "metrics", "at least one"),
        ({"parameters": {"a..b": [1]}}, "parameters.a..b", "key step"),
        ({"parameters": {"x.y": []}}, "parameters.x.y", "at least one value"),
        ({"parameters": {"x.y": {"from": 1, "to": 0, "step": 1}}}, "parameters.x.y", "to >= from"),
        ({"parameters": {"g": {"lvl": 3}}}, "parameters.g.lvl", "mapping of key paths"),
        ({"combine": "zip", "parameters": {"a.b": [1, 2], "c.d": [1]}}, "parameters", "one length"),
        ({"parameters": {"x.y": {"from": 0, "to": 1e6, "step": 1}}}, "parameters.x.y", "at most"),
        ({"scenario": "missing.yaml"}, "scenario", "not found"),
    ],
)
def test_bad_study_files(tmp_path, changes, key, words):
    with pytest.raises(ScenarioError) as info:
        load_study(write_study(tmp_path, **changes))
    assert info.value.key_path == key and words in str(info.value)
    assert str(tmp_path / "study.yaml") in str(info.value)


def test_a_key_beyond_the_scenario_names_the_key(tmp_path):
    study = load_study(write_study(tmp_path, parameters={"platoons[3].members": [2]}))
    with pytest.raises(ScenarioError) as info:
        scenario_for(study, expand(study)[0])
    assert info.value.key_path == "parameters.platoons[3].members"
    assert "index 3 beyond" in str(info.value)


def test_the_scenario_copy_is_a_scenario(tmp_path):
    study = load_study(write_study(tmp_path))
    text = yaml.safe_dump(scenario_for(study, expand(study)[0]))
    assert "outputs" in text and "directory" not in text


@pytest.mark.slow
@pytest.mark.parametrize("path", sorted((REPO / "studies").glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_studies_validate(path, tmp_path):
    study = load_study(path)
    runs = expand(study)
    assert len(write_scenarios(study, runs, tmp_path)) == len(runs) > 1


def test_a_study_file_is_read_with_the_scenario_files_limits(tmp_path):
    with pytest.raises(ScenarioError, match="study file not found"):
        load_study(tmp_path / "none.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"scenario: \xff\n")
    with pytest.raises(ScenarioError, match="not UTF-8"):
        load_study(bad)
    bad.write_text("a: &x [1]\na: *x\n")
    with pytest.raises(ScenarioError, match="key given twice"):
        load_study(bad)
