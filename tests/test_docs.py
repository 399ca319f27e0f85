"""The docs stay true to the code: generated reference up to date, output tables complete."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from platoon_sumo.events import EVENT_COLUMNS, EventKind
from platoon_sumo.recorder import TRAJECTORY_COLUMNS
from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO, URBAN_GRID_NET

OUTPUTS_MD = REPO / "docs" / "outputs.md"


def _section(text: str, heading: str) -> str:
    """The body of a `## heading` section, up to the next `## ` heading."""
    start = text.index(f"## {heading}\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end != -1 else len(text)]


def _first_column(section: str) -> list[str]:
    """Backticked names in the first cell of each row of the section's table."""
    return re.findall(r"^\| `([^`]+)` \|", section, flags=re.MULTILINE)


def test_scenario_reference_is_up_to_date():
    done = subprocess.run(
        [sys.executable, str(REPO / "tools" / "scenario_reference.py"), "--check"],
        capture_output=True,
        text=True,
        cwd=REPO,
        check=False,
    )
    assert done.returncode == 0, done.stderr


def test_outputs_doc_lists_exactly_the_trajectory_columns_in_order():
    text = OUTPUTS_MD.read_text(encoding="utf-8")
    documented = _first_column(_section(text, "`trajectories.csv`"))
    assert documented == list(TRAJECTORY_COLUMNS)
    for name in TRAJECTORY_COLUMNS:
        assert f"`{name}`" in text


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory):
    """A few seconds of one car on the urban grid, no background traffic."""
    folder = tmp_path_factory.mktemp("docs_run")
    scenario = folder / "tiny.yaml"
    scenario.write_text(
        f"network: {{net_file: {URBAN_GRID_NET.as_posix()}}}\n"
        "simulation: {end_s: 3}\n"
        "platoons:\n"
        "  - {id: ego, route: {edges: [left1A1, A1B1]}}\n",
        encoding="utf-8",
    )
    return run(load_plan(scenario), out_dir=folder / "out").directory


def _flat_keys(mapping: dict, prefix: str = "") -> list[str]:
    """Dotted key paths of the summary's values; `versions`, `followers`, `platoons`,
    `string_stability` and `other_trips` (keyed by package / vehicle / platoon ids /
    vehicle classes) are documented as one key each."""
    keys = []
    for key, value in mapping.items():
        if isinstance(value, dict) and key not in (
            "versions",
            "followers",
            "platoons",
            "string_stability",
            "other_trips",
        ):
            keys += _flat_keys(value, f"{prefix}{key}.")
        else:
            keys.append(prefix + key)
    return keys


def test_outputs_doc_lists_every_summary_key(tiny_run):
    summary = json.loads((tiny_run / "summary.json").read_text())
    section = _section(OUTPUTS_MD.read_text(encoding="utf-8"), "`summary.json`")
    assert sorted(_first_column(section)) == sorted(_flat_keys(summary))
    for name in summary["versions"]:
        assert f"`{name}`" in section


def test_outputs_doc_lists_every_event_kind_and_column():
    section = _section(OUTPUTS_MD.read_text(encoding="utf-8"), "`events.csv`")
    assert _first_column(section)[: len(EVENT_COLUMNS)] == list(EVENT_COLUMNS)
    for kind in EventKind:
        assert f"`{kind.value}`" in section, f"event kind {kind.value} not documented"
    metrics = (REPO / "docs" / "metrics.md").read_text(encoding="utf-8")
    for kind in EventKind:
        assert f"`{kind.value}`" in metrics, f"event kind {kind.value} not defined in metrics.md"


def test_outputs_doc_describes_the_files_a_run_writes(tiny_run):
    text = OUTPUTS_MD.read_text(encoding="utf-8")
    for path in sorted(tiny_run.rglob("*")):
        if path.is_file():
            assert f"`{path.relative_to(tiny_run).as_posix()}`" in text
    header = (tiny_run / "tripinfo.csv").read_text().splitlines()[0].split(";")
    assert header[0] == "tripinfo_id"
    assert all(f"`{column}`" in text for column in header)
    traj_header = (tiny_run / "trajectories.csv").read_text().splitlines()[0]
    assert traj_header.split(",") == list(TRAJECTORY_COLUMNS)
