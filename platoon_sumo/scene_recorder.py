"""The scene of a run, for animations: the traffic around the platoons and their scans.

The trajectory table has only the platoon vehicles; drawing a run afterwards also needs
the SUMO vehicles around them and what the lasers saw. `SceneRecorder` keeps both at a
lower rate than the step (`outputs.scene_period_s`) and only near the platoons
(`outputs.scene_radius_m`), so the files stay small (docs/outputs.md):

- `scene.csv`: one row per vehicle within the radius of a platoon vehicle (platoon
  vehicles included) per scene time;
- `scans.npz`: every platoon laser's latest scan at each scene time, ranges as float16
  (REP 117's inf and NaN kept), appended in chunks (numpy arrays in one zip file) so
  memory stays bounded whatever the run's length.

`read_scene` reads both back.
"""

from __future__ import annotations

import json
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from platoon_sumo.errors import UsageError
from platoon_sumo.loop.context import RunContext, RunOutcome, StepHook, StepRecord
from platoon_sumo.recorder import TableWriter

SCENE_FILE = "scene.csv"
SCANS_FILE = "scans.npz"
SCENE_TYPES = {
    "time_s": "f", "vehicle_id": "s", "platoon_id": "s", "member_index": "i", "x_m": "f",
    "y_m": "f", "yaw_rad": "f", "length_m": "f", "width_m": "f", "speed_mps": "f",
}  # fmt: skip
SCENE_COLUMNS = tuple(SCENE_TYPES)
#: Decimals kept of the numeric columns (rows of the buffered values: x, y, yaw, speed).
_DECIMALS = ((0, 3), (1, 3), (2, 4), (5, 3))
#: Columns of a scan's pose array in `scans.npz`.
POSE_COLUMNS = ("time_s", "stamp_s", "origin_x_m", "origin_y_m", "heading_rad")
#: Scene times buffered before they are appended to the files.
FLUSH_FRAMES = 120
_MEMBER = re.compile(r"(ranges|poses)_(\d+)_(\d+)")


class SceneRecorder(StepHook):
    """Writes `scene.csv` and `scans.npz` in `directory` every `period_s` (rounded to
    whole steps, at least one), from the first step with a platoon vehicle in the
    network, keeping the vehicles whose front bumper is within `radius_m` of a platoon
    vehicle's. The world the loop reads holds only vehicles within the sensors' reach of
    the platoons (docs/design.md, ObserveWorld), so a radius beyond it adds nothing."""

    def __init__(self, directory: Path, period_s: float, radius_m: float):
        self.scene_path = directory / SCENE_FILE
        self.scans_path = directory / SCANS_FILE
        self.period_s = period_s
        self.radius_m = radius_m
        self._every_steps = 1
        self._step = 0
        self._writer = TableWriter(self.scene_path, "csv", SCENE_TYPES)
        # the buffered scene times' rows, column-wise: (time, rows) per scene time, the
        # text columns' cells, and the numeric columns (x to speed) per scene time
        self._times: list[tuple[float, int]] = []
        self._ids: list[str] = []
        self._platoons: list[str | None] = []
        self._indices: list[int | None] = []
        self._values: list[NDArray[np.float64]] = []
        self._frames = 0
        self._chunk = 0
        self._lasers: dict[str, int] = {}
        self._meta: list[dict[str, Any]] = []
        self._poses: dict[int, list[tuple[float, ...]]] = {}
        self._ranges: dict[int, list[NDArray[np.float16]]] = {}

    def on_start(self, run: RunContext) -> None:
        self._every_steps = max(1, round(self.period_s / run.dt_s))
        self._writer.open()

    def on_step(self, record: StepRecord) -> None:
        self._step += 1
        vc = record.columns
        if self._step % self._every_steps or not len(vc):
            return
        world = record.world
        dx = world.front_x_m[:, None] - vc.front_x_m[None, :]
        dy = world.front_y_m[:, None] - vc.front_y_m[None, :]
        near = np.flatnonzero(np.hypot(dx, dy).min(axis=1, initial=np.inf) <= self.radius_m)
        ids = [world.ids[i] for i in near.tolist()]
        ours = dict(zip(vc.id, range(len(vc)), strict=True))
        members = [ours.get(vid) for vid in ids]
        self._times.append((round(record.time_s, 6), len(ids)))
        self._ids.extend(ids)
        self._platoons.extend(vc.platoon_id[k] if k is not None else None for k in members)
        self._indices.extend(vc.member_index[k] if k is not None else None for k in members)
        self._values.append(
            np.stack([
                world.front_x_m[near], world.front_y_m[near], world.yaw_rad[near],
                world.length_m[near], world.width_m[near], world.speed_mps[near],
            ])
        )  # fmt: skip
        time_s = self._times[-1][0]
        for vid, platoon_id, member_index, scan in zip(
            vc.id, vc.platoon_id, vc.member_index, vc.scans, strict=True
        ):
            if scan is None:
                continue
            k = self._lasers.get(vid)
            if k is None:
                k = self._lasers[vid] = len(self._meta)
                self._meta.append({
                    "vehicle_id": vid, "platoon_id": platoon_id, "member_index": member_index,
                    "angle_min": scan.angle_min, "angle_increment": scan.angle_increment,
                    "range_min": scan.range_min, "range_max": scan.range_max,
                })  # fmt: skip
            pose = (time_s, scan.stamp_s, scan.origin_x_m, scan.origin_y_m, scan.heading_rad)
            self._poses.setdefault(k, []).append(pose)
            self._ranges.setdefault(k, []).append(scan.ranges.astype(np.float16))
        self._frames += 1
        if self._frames >= FLUSH_FRAMES:
            self.flush()

    def flush(self) -> None:
        """Append the buffered scene times to both files."""
        if self._times:
            times, counts = zip(*self._times, strict=True)
            values = np.concatenate(self._values, axis=1)
            for row, decimals in _DECIMALS:
                values[row] = np.round(values[row], decimals)
            self._writer.write(
                [np.repeat(times, counts), self._ids, self._platoons, self._indices, *values]
            )
        if self._poses:
            arrays: dict[str, NDArray[Any]] = {}
            for k, poses in self._poses.items():
                arrays[f"poses_{k}_{self._chunk}"] = np.array(poses, dtype=np.float64)
                arrays[f"ranges_{k}_{self._chunk}"] = np.stack(self._ranges[k])
            _append_arrays(self.scans_path, arrays)
        self._times, self._ids, self._platoons, self._indices, self._values = [], [], [], [], []
        self._poses.clear()
        self._ranges.clear()
        self._frames = 0
        self._chunk += 1

    def on_end(self, outcome: RunOutcome) -> None:
        self.flush()
        if self._meta:
            _append_arrays(self.scans_path, {"lasers": np.array(json.dumps(self._meta))})


def _append_arrays(path: Path, arrays: dict[str, NDArray[Any]]) -> None:
    """Add arrays as `.npy` members of the zip file `path` (numpy's .npz layout), at
    deflate's fastest level: about half the CPU of the default level for files about
    13 % larger (the scans are mostly `inf`, which any level packs well)."""
    with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        for name, array in arrays.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                np.lib.format.write_array(f, array, allow_pickle=False)


@dataclass(frozen=True)
class ScanSeries:
    """One platoon laser's scans at the scene times (docs/outputs.md, `scans.npz`)."""

    vehicle_id: str
    platoon_id: str
    member_index: int
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    poses: NDArray[np.float64]
    """(n, 5): `POSE_COLUMNS`."""
    ranges_m: NDArray[np.float32]
    """(n, rays), REP 117: +inf nothing within range, -inf closer than range_min, NaN
    a dropout."""


@dataclass(frozen=True)
class Scene:
    traffic: pd.DataFrame
    """`scene.csv`: every vehicle near the platoons per scene time."""
    scans: dict[str, ScanSeries]
    """By vehicle id; empty when no platoon vehicle has a laser."""


def read_scene(directory: Path) -> Scene:
    """The scene files of a results folder; UsageError naming the folder when it has
    none (a run from before they were written, or with `outputs.scene_period_s: null`)."""
    scene_path = directory / SCENE_FILE
    if not scene_path.is_file():
        raise UsageError(
            f"{directory}: no {SCENE_FILE} (the run is older than scene recording, or ran "
            "with outputs.scene_period_s: null); run the scenario again to animate it"
        )
    traffic = pd.read_csv(scene_path, dtype={"vehicle_id": str, "platoon_id": str})
    scans: dict[str, ScanSeries] = {}
    scans_path = directory / SCANS_FILE
    if scans_path.is_file():
        with np.load(scans_path) as data:
            meta = json.loads(data["lasers"].item())
            chunks: dict[tuple[str, int], list[tuple[int, NDArray[Any]]]] = {}
            for name in data.files:
                match = _MEMBER.fullmatch(name)
                if match:
                    kind, k, chunk = match[1], int(match[2]), int(match[3])
                    chunks.setdefault((kind, k), []).append((chunk, data[name]))
        for k, m in enumerate(meta):
            poses, ranges = (
                np.concatenate([a for _, a in sorted(chunks[kind, k], key=lambda c: c[0])])
                for kind in ("poses", "ranges")
            )
            scans[m["vehicle_id"]] = ScanSeries(
                **m, poses=poses, ranges_m=ranges.astype(np.float32)
            )
    return Scene(traffic, scans)
