"""`platoon-sumo scan` (issue 15): the PNG goes into the scenario's results folder or
`--out`, never the working directory, nothing of the user's is replaced, and the figure
shows the scanning car, its predecessor and every other vehicle's outline."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from platoon_sumo.cli import main
from platoon_sumo.results import MANIFEST, NO_RUN, FolderError, add_file, claim
from platoon_sumo.runner import OUTPUT_NAMES
from platoon_sumo.sensors.laser import LaserConfig, LaserScan
from platoon_sumo.sensors.plot import scan_figure
from platoon_sumo.sensors.raycast import cast_rays
from tests.helpers import REPO

URBAN_PLATOON = REPO / "scenarios" / "urban_platoon.yaml"
DEPART_S = 40.0  # the platoon's depart_s in that file
AT_S = DEPART_S + 5.0
VEHICLE = "cars.2"  # a follower: it has a predecessor


def scan_names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.glob("laser_scan_*.png"))


def assert_scan_png(path: Path) -> None:
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    time_s = float(re.fullmatch(rf"laser_scan_{re.escape(VEHICLE)}_t(.+)\.png", path.name)[1])
    assert DEPART_S < time_s <= AT_S  # the latest scan by --at


# -- the command, on the urban platoon shortly after it departs ----------------------------


@pytest.mark.slow
def test_scan_goes_into_the_results_folder_beside_the_users_files(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    results = tmp_path / "results" / URBAN_PLATOON.stem  # its outputs.directory
    results.mkdir(parents=True)
    notes = results / "notes.txt"
    notes.write_text("mine")
    assert main(["scan", str(URBAN_PLATOON), "--at", str(AT_S), "--vehicle", VEHICLE]) == 0
    (name,) = scan_names(results)
    assert_scan_png(results / name)
    assert notes.read_text() == "mine" and not (results / MANIFEST).exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results"]  # not the cwd
    out = capsys.readouterr().out
    assert VEHICLE in out and name in out


@pytest.mark.slow
def test_scan_out_is_a_folder_or_a_png_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "scans"
    args = ["scan", str(URBAN_PLATOON), "--at", str(AT_S), "--vehicle", VEHICLE, "--out"]
    assert main([*args, str(folder)]) == 0  # a new folder
    (first,) = scan_names(folder)
    assert_scan_png(folder / first)
    named = folder / "mine.png"
    named.write_bytes(b"an earlier picture")
    assert main([*args, str(named)]) == 0  # a file the user names: written as asked
    assert named.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert scan_names(folder) == [first]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scans"]


@pytest.mark.slow
def test_scan_draws_a_followers_laser_by_default(tmp_path):
    """The leader has a laser too, but a follower's scan is the one that shows the car
    it follows: without --vehicle the first follower's is drawn."""
    assert main(["scan", str(URBAN_PLATOON), "--at", str(AT_S), "--out", str(tmp_path)]) == 0
    (name,) = scan_names(tmp_path)
    assert name.startswith("laser_scan_cars.1_t")


# -- where a new file goes ----------------------------------------------------------------


def test_a_new_folder_stays_claimable_by_a_run_which_keeps_the_picture(tmp_path):
    folder = tmp_path / "results" / "x"
    png = add_file(folder, "laser_scan_a_t1.png")
    assert png.parent == folder and png.is_file()
    assert json.loads((folder / MANIFEST).read_text())["status"] == NO_RUN
    claimed = claim(folder, "run", OUTPUT_NAMES)
    assert png.is_file() and Path(png.name) in claimed.foreign


def test_a_taken_name_gets_a_number_and_nothing_is_overwritten(tmp_path):
    (tmp_path / "mine.txt").write_text("user's")
    taken = tmp_path / "laser_scan_a_t1.png"
    taken.write_bytes(b"user's picture")
    names = [add_file(tmp_path, taken.name).name for _ in range(2)]
    assert names == ["laser_scan_a_t1_2.png", "laser_scan_a_t1_3.png"]
    assert taken.read_bytes() == b"user's picture" and not (tmp_path / MANIFEST).exists()


@pytest.mark.parametrize("kind", ["report", "comparison"])
def test_a_folder_replaced_whole_is_refused(tmp_path, kind):
    claim(tmp_path, kind).finish("complete")
    with pytest.raises(FolderError, match=kind):
        add_file(tmp_path, "laser_scan_a_t1.png")
    assert scan_names(tmp_path) == []


# -- the figure -----------------------------------------------------------------------------


def test_scan_figure_outlines_vehicles_and_marks_the_scanner_and_its_predecessor():
    # the scanner at the origin heading +x, its predecessor ahead, two others beside
    rects = np.array([[-2.25, 0.0, 0.0, 4.5, 1.8], [10.0, 0.0, 0.0, 4.5, 1.8],
                      [10.0, 5.0, 0.0, 4.5, 1.8], [-8.0, -5.0, 0.0, 4.5, 1.8]])  # fmt: skip
    scanner, predecessor = (0, "p.1"), (1, "p.0")
    config = LaserConfig(-2.3, 2.3, 271, 0.1, 30.0)
    others = np.delete(rects, scanner[0], axis=0)  # a laser does not see its own car
    scan = LaserScan.from_ranges(config, cast_rays([0.0, 0.0], 0.0, config, others), (0, 0), 0.0)
    ax = scan_figure(scan, rects, None, "title", scanner, predecessor).axes[0]
    assert len(ax.patches) == len(rects)
    filled = [p for p in ax.patches if p.get_fill()]
    assert len(filled) == 2  # scanner and predecessor; the others are outlines
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert f"scanning car {scanner[1]}" in legend and f"predecessor {predecessor[1]}" in legend
    assert predecessor[1] in [t.get_text() for t in ax.texts]  # named on the map
    assert ax.get_title().startswith("title")
