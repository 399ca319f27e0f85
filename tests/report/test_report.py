"""Issue acceptance: `platoon-sumo report` on urban_platoon results writes non-empty
figures and report.md; `compare` writes the side-by-side table and overlays."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest

from platoon_sumo.cli import main
from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out

END_S = 95.0  # the platoon departs at 40 s: one signalised junction and a turn


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("urban_platoon_report")
    run(load_plan(REPO / "scenarios" / "urban_platoon.yaml", end_s=END_S), out_dir=out)
    return out


def assert_image(path: Path) -> None:
    assert path.is_file(), path
    image = mpimg.imread(path)
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 200, path
    assert float(np.std(image[..., :3])) > 0.01, f"{path} is blank"


def test_report_writes_figures_and_markdown(results, capsys):
    assert main(["report", str(results)]) == 0
    report = results / "report"
    names = ["map.png", "spacing_speed_cars.png", "time_space_cars.png",
             "string_stability_cars.png", "laser_scan.png"]  # fmt: skip
    for name in names:
        assert_image(report / name)
    text = (report / "report.md").read_text()
    for name in names:
        assert f"]({name})" in text
    assert "| min gap [m] |" in text and "## Vehicles" in text
    assert "report.md" in capsys.readouterr().out


def test_scan_snapshot_marks_the_scanning_car_and_its_predecessor(results):
    """The report's scan shows the car the sensor sits on and the car it follows: their
    rows in the saved footprints are the ones at the sensor and at the predecessor."""
    with np.load(results / "scan_snapshot.npz") as data:
        meta = json.loads(str(data["meta"]))
        rects = data["rectangles"]
    own, pred = rects[meta["scanner_row"]], rects[meta["predecessor_row"]]
    vid = meta["vehicle_id"]
    assert meta["predecessor_id"] == f"cars.{int(vid.split('.')[1]) - 1}"
    traj = pd.read_csv(results / "trajectories.csv")
    at = traj[np.isclose(traj["time_s"], meta["stamp_s"])].set_index("vehicle_id")
    # footprint rows (cx, cy, ...) are centres: half a car behind the front bumper
    for rect, who in ((own, vid), (pred, meta["predecessor_id"])):
        distance = np.hypot(rect[0] - at.loc[who, "x_m"], rect[1] - at.loc[who, "y_m"])
        assert distance < 4.5, who  # within a car length of its front bumper


def test_summary_tables_are_written(results):
    vehicles = pd.read_csv(results / "vehicles.csv")
    assert list(vehicles["vehicle_id"]) == [f"cars.{i}" for i in range(5)]
    assert vehicles.loc[1:, "min_gap_m"].gt(0).all()
    assert vehicles["co2_g"].notna().all()  # SUMO's emission model, via tripinfo
    platoons = pd.read_csv(results / "platoons.csv")
    assert list(platoons["platoon_id"]) == ["cars"]


def test_compare_writes_table_markdown_and_overlays(results, tmp_path):
    out = tmp_path / "cmp"
    assert main(["compare", str(results), str(results), "--out", str(out)]) == 0
    table = pd.read_csv(out / "comparison.csv")
    assert len(table) == 2 and "max_accel_l2_gain" in table
    assert "# Run comparison" in (out / "comparison.md").read_text()
    for name in ("compare_metrics.png", "compare_along_platoon.png", "compare_speeds.png"):
        assert_image(out / name)


def test_report_of_a_folder_we_did_not_write_is_one_error_line(tmp_path, capsys):
    (tmp_path / "FAILED.txt").write_text("SumoError: boom\n")
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not the results of a platoon-sumo run" in err
    assert not (tmp_path / "report").exists()


def test_parquet_trajectories_match_csv(tmp_path, write_scenario):
    base = {
        "network": {"net_file": str(REPO / "networks" / "urban_grid" / "urban_grid.net.xml")},
        "simulation": {"end_s": 4},
        "platoons": [{"id": "ego", "route": {"edges": ["left1A1", "A1B1"]}}],
    }
    csv_dir, pq_dir = tmp_path / "csv", tmp_path / "pq"
    run(load_plan(write_scenario(base, "a.yaml")), out_dir=csv_dir)
    run(load_plan(write_scenario({**base, "outputs": {"format": "parquet", "chunk_rows": 7}},
                                 "b.yaml")), out_dir=pq_dir)  # fmt: skip
    a = pd.read_csv(csv_dir / "trajectories.csv")
    b = pd.read_parquet(pq_dir / "trajectories.parquet")
    assert list(b.columns) == list(a.columns)
    # compare by declared type: CSV reads an all-empty text column as float NaN
    from platoon_sumo.recorder import COLUMN_TYPES

    numeric = [c for c, t in COLUMN_TYPES.items() if t in ("f", "i")]
    pd.testing.assert_frame_equal(a[numeric], b[numeric], check_dtype=False)
    text = [c for c, t in COLUMN_TYPES.items() if t == "s"]
    as_text = pd.read_csv(csv_dir / "trajectories.csv", dtype=dict.fromkeys(text, str))
    assert (as_text[text].fillna("") == b[text].fillna("")).all().all()
