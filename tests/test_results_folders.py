"""Results folders are ours alone, and readers trust nothing: the bad-input catalogue's
cases about where runs, reports and comparisons write, and what they read.

Every case runs the real CLI (`cli.main`) on a short real run (two cars on the straight
road, 3 s) and asserts the exit code, the one-line message and what is on disk
afterwards: nothing of the user's lost or changed, nothing presented as complete.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml

from platoon_sumo.cli import main
from platoon_sumo.results import MANIFEST
from tests.helpers import REPO

NET = REPO / "networks" / "straight" / "straight.net.xml"
PLUGINS = REPO / "tests" / "plugins"


def scenario(**changes: Any) -> dict[str, Any]:
    data: dict[str, Any] = {
        "name": "tiny",
        "simulation": {"step_s": 0.1, "end_s": 3.0, "seed": 1},
        "network": {"net_file": str(NET)},
        "platoons": [
            {
                "id": "p",
                "route": {"edges": ["WE"]},
                "members": 2,
                "spacing_m": 8.0,
                "depart_pos_m": 40.0,
                "actuation": "lane",
                "vehicle": {"model": "bicycle", "length_m": 4.5, "width_m": 1.8},
                "leader": {"type": "route_following"},
                "follower": {"type": "route_following"},
            }
        ],
    }
    data.update(changes)
    return data


def write(tmp: Path, data: dict[str, Any], name: str = "s.yaml") -> Path:
    path = tmp / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def snapshot(folder: Path) -> dict[str, str]:
    """Every file under `folder` with its content hash."""
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def one_error_line(capsys: pytest.CaptureFixture[str], *words: str) -> str:
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A complete run's folder; tests copy it before changing anything."""
    tmp = tmp_path_factory.mktemp("finished")
    out = tmp / "run"
    assert main(["run", str(write(tmp, scenario())), "--out", str(out), "--quiet"]) == 0
    return out


@pytest.fixture
def run_copy(finished: Path, tmp_path: Path) -> Path:
    target = tmp_path / "run"
    shutil.copytree(finished, target)
    return target


def run_with_follower(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    follower: dict[str, Any],
    actuation: str = "lane",
) -> tuple[int, Path]:
    """Run the tiny scenario with a test plug-in as the follower: (exit code, folder)."""
    monkeypatch.syspath_prepend(str(PLUGINS))
    data = scenario()
    data["platoons"][0].update(follower=follower, actuation=actuation)
    out = tmp_path / "out"
    return main(["run", str(write(tmp_path, data)), "--out", str(out), "--quiet"]), out


RAISES_AT_1_5_S = {"type": "failing_controller:FailsAt", "params": {"fail_at_s": 1.5}}


# -- where a run writes ----------------------------------------------------------------


def test_a_run_refuses_a_users_folder_and_leaves_it_as_it_was(tmp_path, capsys):
    user = tmp_path / "thesis"
    (user / "inputs").mkdir(parents=True)
    (user / "inputs" / "measurements.csv").write_text("a,b\n1,2\n")
    (user / "scenario.yaml").write_text("my notes\n")
    before = snapshot(user)
    assert main(["run", str(write(tmp_path, scenario())), "--out", str(user), "--quiet"]) == 2
    one_error_line(capsys, str(user), "not empty", "not written by platoon-sumo")
    assert snapshot(user) == before


def test_force_does_not_open_a_users_folder_either(tmp_path, capsys):
    user = tmp_path / "data"
    user.mkdir()
    (user / "keep.txt").write_text("mine\n")
    path = write(tmp_path, scenario())
    assert main(["run", str(path), "--out", str(user), "--quiet", "--force"]) == 2
    one_error_line(capsys, "not written by platoon-sumo")
    assert snapshot(user) == {"keep.txt": hashlib.sha256(b"mine\n").hexdigest()}


def test_out_naming_a_file_is_refused_and_the_file_kept(tmp_path, capsys):
    target = tmp_path / "results.txt"
    target.write_text("precious\n")
    assert main(["run", str(write(tmp_path, scenario())), "--out", str(target), "--quiet"]) == 2
    one_error_line(capsys, "is a file, not a folder")
    assert target.read_text() == "precious\n"


def test_out_where_no_folder_can_be_made_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    out = blocker / "sub" / "run"
    assert main(["run", str(write(tmp_path, scenario())), "--out", str(out), "--quiet"]) == 2
    one_error_line(capsys, "cannot create the folder")


def test_an_empty_folder_is_used(tmp_path):
    out = tmp_path / "empty"
    out.mkdir()
    assert main(["run", str(write(tmp_path, scenario())), "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / MANIFEST).read_text())["status"] == "complete"


def test_the_manifest_lists_every_file_the_run_wrote(finished):
    manifest = json.loads((finished / MANIFEST).read_text())
    on_disk = set(snapshot(finished)) - {MANIFEST}
    assert manifest["kind"] == "run" and manifest["status"] == "complete"
    assert set(manifest["files"]) == on_disk
    assert {"summary.json", "trajectories.csv", "scenario.yaml"} <= on_disk
    for rel, entry in manifest["files"].items():
        data = (finished / rel).read_bytes()
        assert entry == {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def test_a_rerun_replaces_every_file_of_ours_reports_included_and_keeps_the_users(
    run_copy, tmp_path, capsys
):
    assert main(["report", str(run_copy)]) == 0
    assert (run_copy / "report" / "report.md").is_file()
    (run_copy / "notes.txt").write_text("kept\n")
    path = write(tmp_path, scenario(simulation={"step_s": 0.1, "end_s": 2.0, "seed": 7}))
    assert main(["run", str(path), "--out", str(run_copy), "--quiet"]) == 0
    assert not (run_copy / "report").exists()  # the old seed's report went with its run
    assert (run_copy / "notes.txt").read_text() == "kept\n"
    summary = json.loads((run_copy / "summary.json").read_text())
    assert summary["seed"] == 7
    manifest = json.loads((run_copy / MANIFEST).read_text())
    assert "notes.txt" not in manifest["files"]  # never ours: a later run leaves it too


def test_a_users_file_under_a_name_the_run_writes_is_not_overwritten(run_copy, tmp_path, capsys):
    (run_copy / "inputs" / "my_routes.rou.xml").write_text("<routes/>\n")
    before = snapshot(run_copy)
    assert main(["run", str(write(tmp_path, scenario())), "--out", str(run_copy), "--quiet"]) == 2
    one_error_line(capsys, "did not write", "inputs/my_routes.rou.xml")
    assert snapshot(run_copy) == before


def test_a_results_file_edited_after_the_run_needs_force(run_copy, tmp_path, capsys):
    (run_copy / "vehicles.csv").write_text("edited by hand\n")
    path = write(tmp_path, scenario())
    assert main(["run", str(path), "--out", str(run_copy), "--quiet"]) == 2
    one_error_line(capsys, "vehicles.csv changed since platoon-sumo wrote it", "--force")
    assert (run_copy / "vehicles.csv").read_text() == "edited by hand\n"
    assert main(["run", str(path), "--out", str(run_copy), "--quiet", "--force"]) == 0
    assert (run_copy / "vehicles.csv").read_text().startswith("vehicle_id")


def test_a_killed_runs_folder_needs_force(run_copy, tmp_path, capsys):
    manifest = json.loads((run_copy / MANIFEST).read_text())
    manifest.update(status="running", files={})  # as a SIGKILL leaves it
    (run_copy / MANIFEST).write_text(json.dumps(manifest))
    (run_copy / "summary.json").unlink()
    path = write(tmp_path, scenario())
    assert main(["run", str(path), "--out", str(run_copy), "--quiet"]) == 2
    one_error_line(capsys, "never finished", "--force")
    assert main(["run", str(path), "--out", str(run_copy), "--quiet", "--force"]) == 0
    assert json.loads((run_copy / MANIFEST).read_text())["status"] == "complete"


def test_a_run_does_not_write_into_a_report_folder(finished, tmp_path, capsys):
    reports = tmp_path / "reports"
    assert main(["report", str(finished), "--out", str(reports)]) == 0
    before = snapshot(reports)
    assert main(["run", str(write(tmp_path, scenario())), "--out", str(reports), "--quiet"]) == 2
    one_error_line(capsys, "holds a platoon-sumo report, not a run")
    assert snapshot(reports) == before


# -- faults in user code ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("returns", "what"),
    [
        ("nan_speed", "speed_mps=nan"),
        ("negative_speed", "speed_mps=-3.0"),
        ("infinite_speed", "speed_mps=inf"),
        ("nan_yaw_rate", "yaw_rate_radps=nan"),
        ("infinite_heading", "heading_rad=inf"),
        ("lane_change_two", "lane_change=2"),
        ("none", "returned NoneType"),
        ("text", "returned str"),
    ],
)
def test_a_controller_returning_what_no_car_can_do_ends_the_run_naming_it(
    returns, what, tmp_path, capsys, monkeypatch
):
    follower = {"type": "bad_command:BadCommand", "params": {"returns": returns, "from_s": 2.0}}
    code, out = run_with_follower(tmp_path, monkeypatch, follower)
    assert code == 1
    one_error_line(capsys, "bad_command.BadCommand", "'p.1'", "t=2.00 s", what)
    assert not (out / "summary.json").exists()
    assert "PluginError" in (out / "FAILED.txt").read_text()
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["status"] == "failed"
    rows = (out / "trajectories.csv").read_text().splitlines()
    assert len(rows) > 10  # every step before the bad command is kept


def test_a_raising_controllers_traceback_is_in_failed_txt(tmp_path, capsys, monkeypatch):
    code, out = run_with_follower(tmp_path, monkeypatch, RAISES_AT_1_5_S)
    assert code == 1
    one_error_line(capsys, "failing_controller.FailsAt", "ZeroDivisionError")
    failed = (out / "FAILED.txt").read_text()
    assert "Traceback" in failed and "failing_controller.py" in failed  # for its author


def test_a_crashing_actuation_plugin_is_named_with_its_platoon_and_time(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.syspath_prepend(str(PLUGINS))
    data = scenario()
    data["platoons"][0]["actuation"] = "crashing_actuator:CrashingLane"
    out = tmp_path / "out"
    assert main(["run", str(write(tmp_path, data)), "--out", str(out), "--quiet"]) == 1
    one_error_line(capsys, "crashing_actuator.CrashingLane", "platoon 'p'", "t=1.", "KeyError")
    assert "Traceback" in (out / "FAILED.txt").read_text()


def test_an_internal_error_is_one_line_with_the_traceback_in_failed_txt(
    tmp_path, capsys, monkeypatch
):
    import platoon_sumo.runner

    def broken(*args: Any, **kwargs: Any) -> Any:
        raise RuntimeError("a bug of ours")

    monkeypatch.setattr(platoon_sumo.runner, "summary_tables", broken)
    out = tmp_path / "out"
    assert main(["run", str(write(tmp_path, scenario())), "--out", str(out), "--quiet"]) == 1
    one_error_line(capsys, "internal error", "RuntimeError: a bug of ours", "please report")
    assert "a bug of ours" in (out / "FAILED.txt").read_text()
    assert json.loads((out / MANIFEST).read_text())["status"] == "failed"
    monkeypatch.setenv("PLATOON_SUMO_TRACEBACK", "1")
    with pytest.raises(RuntimeError, match="a bug of ours"):
        main(["run", str(write(tmp_path, scenario())), "--out", str(out), "--quiet"])


# -- report and compare trust nothing ----------------------------------------------------


def test_report_of_a_failed_run_is_refused_and_writes_nothing(tmp_path, capsys, monkeypatch):
    code, out = run_with_follower(tmp_path, monkeypatch, RAISES_AT_1_5_S)
    assert code == 1
    capsys.readouterr()
    assert main(["report", str(out)]) == 2
    one_error_line(capsys, "the run failed")
    assert not (out / "report").exists()


def test_report_of_a_truncated_table_is_refused(run_copy, capsys):
    data = (run_copy / "trajectories.csv").read_bytes()
    (run_copy / "trajectories.csv").write_bytes(data[: len(data) // 2])
    assert main(["report", str(run_copy)]) == 2
    one_error_line(capsys, "trajectories.csv", "truncated")
    assert not (run_copy / "report").exists()


def test_report_of_a_truncated_summary_is_refused(run_copy, capsys):
    text = (run_copy / "summary.json").read_text()
    (run_copy / "summary.json").write_text(text[:100])
    assert main(["report", str(run_copy)]) == 2
    one_error_line(capsys, "summary.json", "truncated")


def test_report_of_an_edited_table_warns_and_goes_on(run_copy, capsys):
    path = run_copy / "vehicles.csv"
    data = bytearray(path.read_bytes())
    data[-2] = ord("9") if data[-2] != ord("9") else ord("8")  # same size, other content
    path.write_bytes(bytes(data))
    assert main(["report", str(run_copy)]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "vehicles.csv was edited after the run" in err


def test_report_refuses_an_out_folder_of_the_users(finished, tmp_path, capsys):
    user = tmp_path / "figures"
    user.mkdir()
    (user / "fig1.png").write_bytes(b"not ours")
    assert main(["report", str(finished), "--out", str(user)]) == 2
    one_error_line(capsys, "not written by platoon-sumo")
    assert snapshot(user) == {"fig1.png": hashlib.sha256(b"not ours").hexdigest()}


def test_report_and_compare_of_runs_without_platoons(tmp_path, capsys):
    path = write(tmp_path, scenario())
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert main(["run", str(path), "--out", str(out), "--quiet", "--no-platoons"]) == 0
    assert main(["report", str(a)]) == 0
    assert "No platoon vehicle drove in this run" in (a / "report" / "report.md").read_text()
    cmp = tmp_path / "cmp"
    assert main(["compare", str(a), str(b), "--out", str(cmp)]) == 0
    assert (cmp / "comparison.md").is_file()


def test_report_of_a_run_whose_platoon_never_departed(tmp_path, capsys):
    data = scenario()
    data["platoons"][0]["depart_s"] = 50.0  # after the end
    out = tmp_path / "out"
    assert main(["run", str(write(tmp_path, data)), "--out", str(out), "--quiet"]) == 0
    assert main(["report", str(out)]) == 0
    assert "No platoon vehicle drove in this run" in (out / "report" / "report.md").read_text()


def test_compare_with_one_unfinished_run_writes_nothing(finished, tmp_path, capsys):
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "FAILED.txt").write_text("boom\n")
    cmp = tmp_path / "cmp"
    assert main(["compare", str(finished), str(broken), "--out", str(cmp)]) == 2
    one_error_line(capsys, str(broken), "not the results of a platoon-sumo run")
    assert not cmp.exists()


def test_compare_replaces_its_own_earlier_comparison_only(finished, tmp_path, capsys):
    cmp = tmp_path / "cmp"
    assert main(["compare", str(finished), str(finished), "--out", str(cmp)]) == 0
    assert main(["compare", str(finished), str(finished), "--out", str(cmp)]) == 0
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "table.csv").write_text("x\n")
    assert main(["compare", str(finished), str(finished), "--out", str(mine)]) == 2
    one_error_line(capsys, "not written by platoon-sumo")
    assert (mine / "table.csv").read_text() == "x\n"


def test_a_controller_returning_nan_with_planar_actuation_is_named_too(
    tmp_path, capsys, monkeypatch
):
    follower = {"type": "bad_command:BadCommand", "params": {"returns": "nan_speed"}}
    code, out = run_with_follower(tmp_path, monkeypatch, follower, actuation="planar")
    assert code == 1
    one_error_line(capsys, "bad_command.BadCommand", "'p.1'", "speed_mps=nan")
    assert json.loads((out / MANIFEST).read_text())["status"] == "failed"


# -- the scan command's time -----------------------------------------------------------


@pytest.mark.parametrize("at", ["-1", "0", "50", "nan", "inf"])
def test_scan_at_a_time_outside_the_run_names_the_option(at, tmp_path, capsys):
    path = write(tmp_path, scenario())
    png = tmp_path / "scan.png"
    assert main(["scan", str(path), "--at", at, "--out", str(png)]) == 2
    one_error_line(capsys, "--at", "not a time of this run", "simulation.end_s = 3 s")
    assert not png.exists()
