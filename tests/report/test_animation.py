"""Issue 15: the scene a run records, `platoon-sumo animate` on the urban platoon's
results (decoded back: frame count, size, not blank, moving), its errors, and the
report's filmstrip."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pandas as pd
import pytest
from PIL import Image

from platoon_sumo import scene_recorder
from platoon_sumo.cli import main
from platoon_sumo.report import animation
from platoon_sumo.report.animation import Timeline
from platoon_sumo.runner import run
from platoon_sumo.scenario import ScenarioSource, load_scenario, prepare
from platoon_sumo.scene_recorder import read_scene
from tests.helpers import REPO

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out

END_S = 70.0  # the platoon departs at 40 s
FLUSH_FRAMES = 7  # several chunks in scans.npz, so reading them back is tested


#: Inside the loop's reach (the 30 m laser plus vehicle sizes), so the radius filters.
RADIUS_M = 20.0
PERIOD_S = 0.3


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("urban_platoon_animation")
    source = load_scenario(REPO / "scenarios" / "urban_platoon.yaml")
    sc = source.scenario
    sc = dataclasses.replace(
        sc, simulation=dataclasses.replace(sc.simulation, end_s=END_S),
        outputs=dataclasses.replace(sc.outputs, scene_radius_m=RADIUS_M,
                                    scene_period_s=PERIOD_S),
    )  # fmt: skip
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(scene_recorder, "FLUSH_FRAMES", FLUSH_FRAMES)
        run(prepare(ScenarioSource(sc, source.path, source.text)), out_dir=out)
    return out


def test_scene_rows_are_near_a_platoon_vehicle_at_the_scene_rate(results):
    scene = pd.read_csv(results / "scene.csv")
    assert len(scene) and scene["platoon_id"].isna().any(), "no traffic recorded"
    for t, rows in scene.groupby("time_s"):
        ours = rows[rows["platoon_id"].notna()]
        assert len(ours), t
        d = np.hypot(rows["x_m"].to_numpy()[:, None] - ours["x_m"].to_numpy()[None, :],
                     rows["y_m"].to_numpy()[:, None] - ours["y_m"].to_numpy()[None, :])  # fmt: skip
        assert d.min(axis=1).max() <= RADIUS_M + 1e-6, t
    steps = np.diff(np.unique(scene["time_s"])) / PERIOD_S
    assert steps.min() == pytest.approx(1.0)
    assert np.allclose(steps, np.round(steps)), "times off the scene period"


def test_scene_platoon_rows_agree_with_the_trajectory_table(results):
    """The scene's platoon rows are where the trajectory table has the members at those
    times, to the scene's rounding (mm, 1e-4 rad), each member once a scene time. (The
    speed is SUMO's, which differs from ours where our model drives the car.)"""
    scene = pd.read_csv(results / "scene.csv", dtype={"vehicle_id": str, "platoon_id": str})
    ours = scene[scene["platoon_id"].notna()]
    assert not ours.duplicated(["time_s", "vehicle_id"]).any()
    table = pd.read_csv(results / "trajectories.csv", dtype={"vehicle_id": str})
    both = ours.merge(table, on=["time_s", "vehicle_id"], suffixes=("", "_table"))
    assert len(both) == len(ours), "scene rows missing from the trajectory table"
    assert (both["member_index"] == both["member_index_table"]).all()
    for column in ("x_m", "y_m"):
        assert np.abs(both[column] - both[f"{column}_table"]).max() <= 5e-4 + 1e-9, column
    turn = np.angle(np.exp(1j * (both["yaw_rad"] - both["yaw_rad_table"])))
    assert np.abs(turn).max() <= 5e-5 + 1e-9


def test_scans_read_back_whole_from_chunks(results):
    scene = read_scene(results)
    traffic = scene.traffic
    members = sorted(traffic.dropna(subset=["platoon_id"])["vehicle_id"].unique())
    assert sorted(scene.scans) == members  # every member carries a laser here
    for vid, series in scene.scans.items():
        times = np.sort(traffic.loc[traffic["vehicle_id"] == vid, "time_s"].to_numpy())
        assert np.array_equal(series.poses[:, 0], times), vid
        assert series.ranges_m.shape[0] == len(times) > FLUSH_FRAMES
        assert np.isfinite(series.ranges_m).any(), f"{vid}: the laser never hit anything"
    files = json.loads((results / "manifest.json").read_text())["files"]
    assert {"scene.csv", "scans.npz"} <= set(files)


def test_timeline_interpolates_between_scene_times(results):
    scene = read_scene(results)
    timeline = Timeline(scene.traffic)
    t0, t1 = timeline.times_s[len(timeline.times_s) // 2 : len(timeline.times_s) // 2 + 2]
    a, b, mid = timeline.at(t0), timeline.at(t1), timeline.at((t0 + t1) / 2)
    vid = a.ids[0]
    i, j, k = a.find(vid), b.find(vid), mid.find(vid)
    assert i is not None and j is not None and k is not None
    assert mid.x_m[k] == pytest.approx((a.x_m[i] + b.x_m[j]) / 2)
    assert mid.y_m[k] == pytest.approx((a.y_m[i] + b.y_m[j]) / 2)


def _decode_mp4(path: Path) -> tuple[dict, list[np.ndarray]]:
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    return meta, [np.frombuffer(f, np.uint8).reshape(height, width, 3) for f in reader]


def _assert_moving_frames(frames: list[np.ndarray], count: int, size: tuple[int, int]) -> None:
    assert abs(len(frames) - count) <= 1
    for frame in frames:
        assert frame.shape[:2] == (size[1], size[0])
        assert frame.astype(float).var() > 0, "blank frame"
    assert not np.array_equal(frames[0], frames[-1]), "nothing moves"


def test_animate_writes_an_mp4_that_decodes(results, tmp_path, capsys):
    video, fps, size, start, end = tmp_path / "a.mp4", 8, (320, 240), 50.0, 53.0
    assert main(["animate", str(results), "--from", str(start), "--to", str(end), "--fps",
                 str(fps), "--size", f"{size[0]}x{size[1]}", "--out", str(video)]) == 0  # fmt: skip
    meta, frames = _decode_mp4(video)
    assert meta["codec"] == "h264"
    _assert_moving_frames(frames, round((end - start) * fps), size)
    captured = capsys.readouterr()
    assert "frames/s" in captured.out and "frame " in captured.err


def test_animate_writes_a_gif_for_a_gif_name(results, tmp_path):
    video, fps, size, start, end = tmp_path / "a.gif", 5, (200, 160), 60.0, 62.0
    assert main(["animate", str(results), "--vehicle", "cars.2", "--from", str(start),
                 "--to", str(end), "--fps", str(fps), "--size", f"{size[0]}x{size[1]}",
                 "--out", str(video), "--quiet"]) == 0  # fmt: skip
    with Image.open(video) as gif:
        frames = []
        for k in range(gif.n_frames):
            gif.seek(k)
            frames.append(np.asarray(gif.convert("RGB")))
    _assert_moving_frames(frames, round((end - start) * fps), size)


def test_without_ffmpeg_animate_falls_back_to_a_gif(results, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(animation, "ffmpeg_exe", lambda: None)
    assert main(["animate", str(results), "--from", "60", "--to", "60.5", "--size", "96x64",
                 "--out", str(tmp_path / "a.mp4"), "--quiet"]) == 0  # fmt: skip
    assert (tmp_path / "a.gif").is_file() and not (tmp_path / "a.mp4").exists()
    assert "writing a GIF" in capsys.readouterr().err


def test_a_folder_without_scene_is_one_error_line(results, tmp_path, capsys):
    older = tmp_path / "older"
    shutil.copytree(results, older)
    manifest = json.loads((older / "manifest.json").read_text())
    for name in ("scene.csv", "scans.npz"):  # as a run from before scene recording
        (older / name).unlink()
        del manifest["files"][name]
    (older / "manifest.json").write_text(json.dumps(manifest))
    assert main(["animate", str(older)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(older) in err and "no scene.csv" in err
    assert not list(older.glob("animation.*"))


def test_an_unknown_vehicle_is_one_error_line(results, capsys):
    assert main(["animate", str(results), "--vehicle", "cars.9"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--vehicle cars.9" in err
    assert "Traceback" not in err


def test_report_embeds_the_filmstrip(results, tmp_path):
    assert main(["report", str(results), "--out", str(tmp_path / "report")]) == 0
    strip = tmp_path / "report" / "filmstrip.png"
    with Image.open(strip) as image:
        pixels = np.asarray(image.convert("RGB"))
    assert pixels.shape[1] > 2 * pixels.shape[0], "not a strip of frames"
    assert pixels.astype(float).var() > 0
    assert "](filmstrip.png)" in (tmp_path / "report" / "report.md").read_text()
