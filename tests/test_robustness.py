"""tools/robustness.py on a CI-sized corpus, through its command line with real SUMO runs:
one netgenerate grid and one network shipped with eclipse-sumo, 90 simulated seconds,
two platoons each. The full corpus and its table are in docs/real_networks.md.
"""

from __future__ import annotations

import csv
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import REPO

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out

TOOL = REPO / "tools" / "robustness.py"
#: In corpus order (shipped networks first), the order of the table.
NETWORKS = ("cross", "grid4_priority")
#: Short run: platoons depart at 10 and 25 s; the cross's routes (about 350 m) let the
#: first platoon arrive by 90 s.
SHORT = ("--end", "90", "--warmup", "10", "--stagger", "15", "--platoons", "2")
COLUMNS = (
    "network", "nodes", "edges", "signalised", "routes", "planned", "departed", "arrived",
    "collisions", "collisions_platoon_at_fault", "sumo_collisions_with_platoons",
    "sumo_platoon_collider", "sumo_platoon_victim", "red_lights", "stuck", "gridlocks",
    "gridlocks_without",
    "teleports", "standoffs", "in_view_share", "human_finished", "human_finished_without",
    "human_travel_s", "human_travel_without_s", "wall_with_s", "cpu_with_s",
    "wall_without_s", "cpu_without_s", "status", "notes",
)  # fmt: skip


DOC_BEFORE = "# Doc\n\nBefore.\n\n<!-- robustness -->\nold table\n<!-- /robustness -->\n\nAfter.\n"


def robustness(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(TOOL), *args], capture_output=True, text=True, cwd=cwd, check=False
    )


def read_rows(work: Path) -> dict[str, dict[str, str]]:
    with (work / "robustness.csv").open(newline="", encoding="utf-8") as f:
        return {row["network"]: row for row in csv.DictReader(f)}


@pytest.fixture(scope="module")
def corpus(tmp_path_factory: pytest.TempPathFactory):
    work = tmp_path_factory.mktemp("robustness") / "work"
    doc = work.parent / "doc.md"
    doc.write_text(DOC_BEFORE, encoding="utf-8")
    done = robustness(
        "--networks", ",".join(NETWORKS), *SHORT, "--work", str(work), "--doc", str(doc),
        cwd=work.parent,
    )  # fmt: skip
    return done, work


def test_every_network_gets_a_complete_row(corpus) -> None:
    done, work = corpus
    assert done.returncode == 0, done.stderr
    rows = read_rows(work)
    assert list(rows) == list(NETWORKS)
    for name, row in rows.items():
        assert set(COLUMNS) <= set(row), f"{name}: missing {set(COLUMNS) - set(row)}"
        assert row["status"] == "ok", row
        assert int(row["planned"]) == 8
        assert int(row["departed"]) > 0
        # counted (what they are is the package's business, not the harness's)
        assert int(row["collisions"]) >= 0 and int(row["red_lights"]) >= 0
        assert 0 <= int(row["collisions_platoon_at_fault"]) <= int(row["collisions"])
        assert 0.0 <= float(row["in_view_share"]) <= 1.0
        assert int(row["nodes"]) > 0 and int(row["edges"]) > 0
        # the comparison without platoons was run and read
        assert row["human_finished_without"] != "" and row["gridlocks_without"] != ""
        assert float(row["cpu_with_s"]) > 0 and float(row["cpu_without_s"]) > 0
    assert int(rows["cross"]["signalised"]) == 1
    assert int(rows["cross"]["arrived"]) > 0


def test_progress_table_and_inputs_are_written(corpus) -> None:
    done, work = corpus
    progress = [ln for ln in done.stderr.splitlines() if ln.startswith("[")]
    assert len(progress) == len(NETWORKS)
    assert progress[0].startswith(f"[1/2] {NETWORKS[0]}: ok")
    table = (work / "robustness.md").read_text(encoding="utf-8")
    assert "| network |" in table and "with / without" in table
    for name in NETWORKS:
        assert f"| {name} |" in table
        folder = work / name
        assert (folder / "scenario.yaml").is_file() and (folder / "background.rou.xml").is_file()
        assert (folder / "with_platoons" / "summary.json").is_file()
        assert (folder / "without_platoons" / "summary.json").is_file()
    doc = (work.parent / "doc.md").read_text(encoding="utf-8")
    assert doc.startswith("# Doc\n\nBefore.\n\n<!-- robustness -->\nProduced by `python ")
    assert doc.endswith(f"{table.strip()}\n<!-- /robustness -->\n\nAfter.\n")
    assert "old table" not in doc
    assert (work / "grid4_priority" / "net.net.xml").is_file()  # built by netgenerate
    assert not (work / "cross" / "net.net.xml").exists()  # the shipped file, as shipped


def test_inputs_are_reproducible(corpus, tmp_path: Path) -> None:
    _, first = corpus
    again = tmp_path / "again"
    done = robustness("--networks", "cross", *SHORT, "--work", str(again), "--no-run", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert read_rows(again)["cross"]["status"] == "prepared, not run"
    for name in ("scenario.yaml", "background.rou.xml"):
        a, b = (
            # randomTrips.py's header comment has the date and the folder
            re.sub(
                r"<!--.*?-->", "", (w / "cross" / name).read_text(encoding="utf-8"), flags=re.S
            ).replace(str(w), "WORK")
            for w in (first, again)
        )
        assert a == b, name


def test_unknown_network_is_one_clear_error(tmp_path: Path) -> None:
    done = robustness("--networks", "crosss", "--work", str(tmp_path / "w"), cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "error: --networks: unknown network 'crosss' (did you mean 'cross'?); "
        "`--list` shows the corpus"
    ]
    assert not (tmp_path / "w").exists()


def test_a_folder_not_made_by_the_tool_is_refused_untouched(tmp_path: Path) -> None:
    work = tmp_path / "mine"
    work.mkdir()
    (work / "notes.txt").write_text("keep me", encoding="utf-8")
    done = robustness("--networks", "cross", "--work", str(work), cwd=tmp_path)
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1
    assert "not empty and was not made by this tool" in done.stderr
    assert [p.name for p in work.iterdir()] == ["notes.txt"]


def test_a_network_that_fails_to_build_is_a_row_not_a_crash(tmp_path: Path) -> None:
    broken = tmp_path / "broken.net.xml"
    broken.write_text("<net><edge id='a'", encoding="utf-8")
    work = tmp_path / "work"
    done = robustness("--add", str(broken), "--networks", "added_broken", "--work", str(work),
                      cwd=tmp_path)  # fmt: skip
    assert done.returncode == 1
    row = read_rows(work)["added_broken"]
    assert row["status"].startswith("build failed: ")
    assert "\n" not in row["status"]
    assert "[1/1] added_broken: build failed" in done.stderr
