"""Animations of finished runs, and the report's filmstrip of key moments.

Both are drawn from the run's scene files (`scene_recorder`) by one `FrameView`: the
network (`figures.draw_network`), the other traffic as grey outlines, platoon vehicles
filled in their platoon's colour with the leader starred, one vehicle's laser rays and
hit points, and a clock, in a window that follows that vehicle. The scene is kept at a
lower rate than the step, so positions between two scene times are interpolated, and the
latest scan moves with its car until the next one.

The frames of a video reuse the same artists (only their data changes), and are sent
straight from the canvas to ffmpeg (the `imageio-ffmpeg` wheel's binary, H.264); a GIF
(Pillow) is written instead where that binary is missing, or when asked for by name.
"""

from __future__ import annotations

import itertools
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from platoon_sumo.errors import UsageError, did_you_mean
from platoon_sumo.geometry import footprints_from_front_bumper, rectangle_corners, wrap_angle
from platoon_sumo.report import figures
from platoon_sumo.results import check_finished_run
from platoon_sumo.scene_recorder import SCENE_FILE, ScanSeries, Scene, read_scene

FloatArray = NDArray[np.float64]
#: Drawn width of every lane: the network's lane lines are centre lines.
LANE_WIDTH_M = 3.2
#: At most this many rays of a scan are drawn as lines (every hit is drawn as a dot).
RAYS_DRAWN = 120
#: Two scene times further apart than this many periods are not interpolated between.
GAP_PERIODS = 1.5
LASER_COLOR = (0.85, 0.1, 0.1)
DPI = 100

Progress = Callable[[int, int, float], None]
"""Called after each frame with (frames done, frames in all, seconds since the start)."""


@dataclass(frozen=True)
class Vehicles:
    """The scene's vehicles at one time (front bumper poses)."""

    ids: NDArray[np.str_]
    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    length_m: FloatArray
    width_m: FloatArray
    platoon_id: NDArray[np.str_]
    """'' for the other traffic."""
    member_index: NDArray[np.int64]
    """-1 for the other traffic."""

    def find(self, vehicle_id: str) -> int | None:
        hits = np.flatnonzero(self.ids == vehicle_id)
        return int(hits[0]) if len(hits) else None

    def corners(self, rows: NDArray[np.bool_]) -> FloatArray:
        """(n, 4, 2) outline corners of the selected vehicles."""
        rects = footprints_from_front_bumper(
            self.x_m[rows], self.y_m[rows], self.yaw_rad[rows],
            self.length_m[rows], self.width_m[rows],
        )  # fmt: skip
        return rectangle_corners(rects)


class Timeline:
    """The scene's vehicles at any time: each scene time as arrays, and the poses
    between two consecutive scene times interpolated (a vehicle seen only at the first
    stays where it was, one seen only at the second appears there)."""

    def __init__(self, traffic: pd.DataFrame):
        table = traffic.sort_values(["time_s", "vehicle_id"], kind="stable")
        self.times_s = np.unique(table["time_s"].to_numpy(dtype=float))
        gaps = np.diff(self.times_s)
        self.period_s = float(gaps.min()) if len(gaps) else math.inf
        starts = np.searchsorted(table["time_s"].to_numpy(dtype=float), self.times_s)
        bounds = [*starts.tolist(), len(table)]
        cols = {
            "ids": table["vehicle_id"].to_numpy(dtype=str),
            "x_m": table["x_m"].to_numpy(dtype=float),
            "y_m": table["y_m"].to_numpy(dtype=float),
            "yaw_rad": table["yaw_rad"].to_numpy(dtype=float),
            "length_m": table["length_m"].to_numpy(dtype=float),
            "width_m": table["width_m"].to_numpy(dtype=float),
            "platoon_id": table["platoon_id"].fillna("").to_numpy(dtype=str),
            "member_index": table["member_index"].fillna(-1).to_numpy(dtype=np.int64),
        }
        self.frames = [
            Vehicles(**{k: v[a:b] for k, v in cols.items()}) for a, b in itertools.pairwise(bounds)
        ]
        self._matches: dict[int, NDArray[np.int64]] = {}

    def at(self, time_s: float) -> Vehicles:
        i = int(np.clip(np.searchsorted(self.times_s, time_s, side="right") - 1, 0, None))
        f0 = self.frames[i]
        if i + 1 == len(self.frames) or time_s <= self.times_s[i]:
            return f0
        t0, t1 = self.times_s[i], self.times_s[i + 1]
        if t1 - t0 > GAP_PERIODS * self.period_s:
            return f0
        f1, w = self.frames[i + 1], (time_s - t0) / (t1 - t0)
        match = self._match(i)
        both = match >= 0
        j = match[both]
        x, y, yaw = f0.x_m.copy(), f0.y_m.copy(), f0.yaw_rad.copy()
        x[both] += w * (f1.x_m[j] - x[both])
        y[both] += w * (f1.y_m[j] - y[both])
        yaw[both] += w * wrap_angle(f1.yaw_rad[j] - yaw[both])
        new = np.ones(len(f1.ids), dtype=bool)
        new[j] = False
        return Vehicles(*(
            np.concatenate((a, b[new])) for a, b in (
                (f0.ids, f1.ids), (x, f1.x_m), (y, f1.y_m), (yaw, f1.yaw_rad),
                (f0.length_m, f1.length_m), (f0.width_m, f1.width_m),
                (f0.platoon_id, f1.platoon_id), (f0.member_index, f1.member_index),
            )
        ))  # fmt: skip

    def _match(self, i: int) -> NDArray[np.int64]:
        """For each vehicle of scene time i, its row at time i + 1 (-1: gone)."""
        if i not in self._matches:
            rows = {vid: k for k, vid in enumerate(self.frames[i + 1].ids)}
            self._matches[i] = np.array([rows.get(v, -1) for v in self.frames[i].ids], dtype=int)
        return self._matches[i]

    def span_s(self, vehicle_id: str) -> tuple[float, float]:
        """First and last scene time at which the vehicle is in the scene."""
        seen = [t for t, f in zip(self.times_s, self.frames, strict=True) if vehicle_id in f.ids]
        return float(seen[0]), float(seen[-1])


class FrameView:
    """One frame of the scene on `ax`, following `vehicle_id` in a `window_m` x
    `height_m` window; `draw(t)` only changes the artists' data."""

    def __init__(
        self, ax: Any, scene: Scene, timeline: Timeline, net_file: Path | None,
        vehicle_id: str, window_m: float, height_m: float, legend: bool = True,
    ):  # fmt: skip
        from matplotlib.collections import LineCollection, PolyCollection

        self.ax, self.timeline, self.vehicle_id = ax, timeline, vehicle_id
        self.window_m, self.height_m = window_m, height_m
        self.scan = scene.scans.get(vehicle_id)
        rows = scene.traffic[scene.traffic["vehicle_id"] == vehicle_id]
        self._track = (
            rows["time_s"].to_numpy(dtype=float), rows["x_m"].to_numpy(dtype=float),
            rows["y_m"].to_numpy(dtype=float),
        )  # fmt: skip
        platoons = sorted(scene.traffic["platoon_id"].dropna().unique())
        cmap = figures._plt().get_cmap("tab10")
        self.colors = {pid: cmap(k % 10) for k, pid in enumerate(platoons)}
        lanes = figures.draw_network(ax, net_file)
        if lanes is not None:  # lane-wide bands at this scale
            width_pt = ax.get_position().width * ax.figure.get_figwidth() * 72.0
            lanes.set_linewidth(LANE_WIDTH_M * width_pt / window_m)
        self.others = ax.add_collection(PolyCollection(
            [], facecolors="white", edgecolors="0.35", linewidths=0.8, zorder=3))  # fmt: skip
        self.ours = ax.add_collection(PolyCollection([], edgecolors="k", zorder=4))
        self.rays = ax.add_collection(LineCollection(
            [], colors=[(*LASER_COLOR, 0.2)], linewidths=0.5, zorder=5))  # fmt: skip
        (self.hits,) = ax.plot([], [], ls="", marker=".", ms=2.5, color=LASER_COLOR, zorder=6)
        (self.leaders,) = ax.plot([], [], ls="", marker="*", ms=9, mfc="white", mec="k",
                                  mew=0.8, zorder=7)  # fmt: skip
        self.clock = ax.text(
            0.02, 0.98, "", transform=ax.transAxes, va="top", ha="left", fontsize=9, zorder=8,
            bbox={"facecolor": "white", "edgecolor": "0.6", "alpha": 0.85},
        )  # fmt: skip
        if legend:
            self._legend(ax)
        ax.set_xticks([])
        ax.set_yticks([])

    def _legend(self, ax: Any) -> None:
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch

        handles: list[Any] = [Patch(facecolor=c, edgecolor="k", label=f"platoon {p}")
                              for p, c in self.colors.items()]  # fmt: skip
        handles += [
            Line2D([], [], ls="", marker="*", ms=9, mfc="white", mec="k", label="leader"),
            Patch(facecolor="white", edgecolor="0.35", label="other traffic"),
        ]
        if self.scan is not None:
            handles.append(Line2D([], [], color=LASER_COLOR, marker=".", label="laser hits"))
        ax.legend(handles=handles, loc="lower right", fontsize=7, framealpha=0.85)

    def draw(self, time_s: float) -> None:
        now = self.timeline.at(time_s)
        ours = now.member_index >= 0
        self.others.set_verts(now.corners(~ours))
        self.ours.set_verts(now.corners(ours))
        pids = now.platoon_id[ours]
        self.ours.set_facecolor([self.colors[p] for p in pids])
        chosen = now.ids[ours] == self.vehicle_id
        self.ours.set_linewidth(np.where(chosen, 2.0, 0.6))
        lead = ours & (now.member_index == 0)
        cx, cy = _centres(now, lead)
        self.leaders.set_data(cx, cy)
        rays, hits = self._laser(now, time_s)
        self.rays.set_segments(rays)
        self.hits.set_data(hits[:, 0], hits[:, 1])
        t, x, y = self._track
        centre_x, centre_y = float(np.interp(time_s, t, x)), float(np.interp(time_s, t, y))
        self.ax.set_xlim(centre_x - self.window_m / 2, centre_x + self.window_m / 2)
        self.ax.set_ylim(centre_y - self.height_m / 2, centre_y + self.height_m / 2)
        self.clock.set_text(f"t = {time_s:7.2f} s   following {self.vehicle_id}")

    def _laser(self, now: Vehicles, time_s: float) -> tuple[FloatArray, FloatArray]:
        """Ray segments (m, 2, 2) and hit points (h, 2) of the latest scan, carried
        along with its car since the scene time it was kept at."""
        none = (np.empty((0, 2, 2)), np.empty((0, 2)))
        scan, row = self.scan, now.find(self.vehicle_id)
        if scan is None or row is None:
            return none
        j = int(np.searchsorted(scan.poses[:, 0], time_s, side="right")) - 1
        if j < 0 or time_s - scan.poses[j, 0] > GAP_PERIODS * self.timeline.period_s:
            return none
        then = self.timeline.at(float(scan.poses[j, 0]))
        k = then.find(self.vehicle_id)
        if k is None:
            return none
        origin, heading = _carry(
            scan.poses[j, 2:4], float(scan.poses[j, 4]),
            (then.x_m[k], then.y_m[k], then.yaw_rad[k]),
            (now.x_m[row], now.y_m[row], now.yaw_rad[row]),
        )  # fmt: skip
        return _rays(scan, j, origin, heading)


def _centres(v: Vehicles, rows: NDArray[np.bool_]) -> tuple[FloatArray, FloatArray]:
    half = 0.5 * v.length_m[rows]
    yaw = v.yaw_rad[rows]
    return v.x_m[rows] - half * np.cos(yaw), v.y_m[rows] - half * np.sin(yaw)


def _carry(
    origin: FloatArray, heading_rad: float, then: tuple[float, float, float],
    now: tuple[float, float, float],
) -> tuple[FloatArray, float]:  # fmt: skip
    """A sensor pose kept when its car's front bumper was at `then` (x, y, yaw), moved
    with the car to `now`."""
    dx, dy = origin[0] - then[0], origin[1] - then[1]
    turn = now[2] - then[2]
    c, s = math.cos(turn), math.sin(turn)
    moved = np.array([now[0] + c * dx - s * dy, now[1] + s * dx + c * dy])
    return moved, heading_rad + turn


def _rays(
    scan: ScanSeries, j: int, origin: FloatArray, heading_rad: float
) -> tuple[FloatArray, FloatArray]:
    """Every `RAYS_DRAWN`-th ray of scan j (to its hit, or to the range where nothing
    was hit) and every hit point, from the sensor pose given."""
    ranges = scan.ranges_m[j]
    angles = heading_rad + scan.angle_min + scan.angle_increment * np.arange(len(ranges))
    direction = np.column_stack((np.cos(angles), np.sin(angles)))
    hit = np.isfinite(ranges)
    hits = origin + ranges[hit, None] * direction[hit]
    drawn = np.zeros(len(ranges), dtype=bool)
    drawn[:: max(1, math.ceil(len(ranges) / RAYS_DRAWN))] = True
    drawn &= hit | (ranges == np.inf)  # too close or a dropout: no ray to draw
    reach = np.where(hit, ranges, scan.range_max)[drawn]
    ends = origin + reach[:, None] * direction[drawn]
    segments = np.stack((np.broadcast_to(origin, ends.shape), ends), axis=1)
    return segments, hits


def default_vehicle(scene: Scene) -> str:
    """The first follower with scans (lowest member index, then id), else the first
    vehicle with scans, else the first platoon vehicle."""
    if scene.scans:
        return min(scene.scans.values(), key=lambda s: (s.member_index == 0, s.member_index,
                                                        s.vehicle_id)).vehicle_id  # fmt: skip
    ours = scene.traffic.dropna(subset=["platoon_id"])
    return str(ours.sort_values(["member_index", "vehicle_id"])["vehicle_id"].iloc[0])


def _check_vehicle(scene: Scene, directory: Path, vehicle_id: str) -> None:
    ours = sorted(scene.traffic.dropna(subset=["platoon_id"])["vehicle_id"].unique())
    if vehicle_id not in ours:
        hint = did_you_mean(vehicle_id, ours)
        raise UsageError(
            f"--vehicle {vehicle_id}: no platoon vehicle of that id in {directory / SCENE_FILE}"
            f" ({hint or 'platoon vehicles: ' + ', '.join(ours[:8])})"
        )


@dataclass(frozen=True)
class Animation:
    path: Path
    frames: int
    render_s: float
    """Wall-clock time drawing and encoding the frames."""


def ffmpeg_exe() -> str | None:
    """The ffmpeg binary bundled with imageio-ffmpeg, or None where it is missing."""
    try:
        import imageio_ffmpeg

        return str(imageio_ffmpeg.get_ffmpeg_exe())
    except (ImportError, RuntimeError):
        return None


def animate(
    directory: str | Path,
    out: str | Path | None = None,
    vehicle_id: str | None = None,
    start_s: float | None = None,
    end_s: float | None = None,
    fps: float = 10.0,
    size_px: tuple[int, int] = (800, 600),
    window_m: float = 120.0,
    progress: Progress | None = None,
    warn: Callable[[str], None] | None = None,
) -> Animation:
    """Write a video of a finished run: MP4 (H.264), or GIF when `out` ends in .gif or
    no ffmpeg is available. One frame every 1/fps simulated seconds from `start_s` to
    `end_s` (default: the chosen vehicle's time in the scene), played in real time."""
    directory = Path(directory)
    for message in check_finished_run(directory):
        if warn is not None:
            warn(message)
    scene = read_scene(directory)
    if scene.traffic.empty:
        raise UsageError(f"{directory / SCENE_FILE}: empty (no platoon vehicle drove)")
    vehicle_id = vehicle_id or default_vehicle(scene)
    _check_vehicle(scene, directory, vehicle_id)
    width_px, height_px = size_px
    if width_px < 16 or height_px < 16 or width_px % 2 or height_px % 2:
        raise UsageError(f"--size {width_px}x{height_px}: expected even numbers >= 16 (H.264)")
    if not (fps > 0 and math.isfinite(fps)):
        raise UsageError(f"--fps {fps}: expected a number > 0")
    if not (window_m > 0 and math.isfinite(window_m)):
        raise UsageError(f"--window {window_m}: expected a width > 0 m")
    timeline = Timeline(scene.traffic)
    first, last = timeline.span_s(vehicle_id)
    start_s = first if start_s is None else start_s
    end_s = last if end_s is None else end_s
    if not timeline.times_s[0] <= start_s < end_s <= timeline.times_s[-1] + 1e-9:
        raise UsageError(
            f"--from {start_s:g} --to {end_s:g}: expected from < to within the scene's "
            f"{timeline.times_s[0]:g} to {timeline.times_s[-1]:g} s"
        )
    frames = round((end_s - start_s) * fps)
    if frames < 1:
        raise UsageError(
            f"--from {start_s:g} --to {end_s:g}: shorter than one frame at --fps {fps:g}"
        )
    path = Path(out) if out is not None else directory / "animation.mp4"
    exe = None if path.suffix.lower() == ".gif" else ffmpeg_exe()
    if exe is None and path.suffix.lower() != ".gif":
        path = path.with_suffix(".gif")
        if warn is not None:
            warn(f"no ffmpeg (pip install imageio-ffmpeg): writing a GIF, {path}")
    summary = json.loads((directory / "summary.json").read_text(encoding="utf-8"))
    net = summary.get("network_file")
    plt = figures._plt()
    fig = plt.figure(figsize=(width_px / DPI, height_px / DPI), dpi=DPI)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    view = FrameView(ax, scene, timeline, Path(net) if net else None, vehicle_id, window_m,
                     window_m * height_px / width_px)  # fmt: skip
    sink: _Mp4 | _Gif = _Mp4(path, size_px, fps) if exe is not None else _Gif(path, fps)
    started = time.perf_counter()
    try:
        for k in range(frames):
            view.draw(start_s + k / fps)
            fig.canvas.draw()
            sink.add(np.asarray(fig.canvas.buffer_rgba()))
            if progress is not None:
                progress(k + 1, frames, time.perf_counter() - started)
        sink.close()
    except BaseException:
        sink.close()
        path.unlink(missing_ok=True)  # no half-written video
        raise
    finally:
        plt.close(fig)
    return Animation(path, frames, time.perf_counter() - started)


class _Mp4:
    """RGBA frames piped to ffmpeg (libx264, yuv420p: plays everywhere)."""

    def __init__(self, path: Path, size_px: tuple[int, int], fps: float):
        import imageio_ffmpeg

        self._writer = imageio_ffmpeg.write_frames(
            str(path), size_px, pix_fmt_in="rgba", fps=fps, codec="libx264",
            macro_block_size=1, output_params=["-crf", "23"],
        )  # fmt: skip
        self._writer.send(None)  # start ffmpeg

    def add(self, rgba: NDArray[np.uint8]) -> None:
        self._writer.send(np.ascontiguousarray(rgba))

    def close(self) -> None:
        self._writer.close()


class _Gif:
    """Frames kept as 8-bit palette images, written as one GIF at the end."""

    def __init__(self, path: Path, fps: float):
        self.path, self.fps = path, fps
        self._frames: list[Any] = []

    def add(self, rgba: NDArray[np.uint8]) -> None:
        from PIL import Image

        self._frames.append(Image.fromarray(rgba[..., :3]).quantize(colors=128))

    def close(self) -> None:
        if self._frames:
            first, *rest = self._frames
            first.save(self.path, save_all=True, append_images=rest,
                       duration=round(1000.0 / self.fps), loop=0, optimize=False)  # fmt: skip
        self._frames = []


def progress_line(stream: Any = None) -> Progress:
    """Progress of a render on `stream` (default: stderr): one line rewritten on a
    terminal, else a line every 10 %."""
    stream = stream if stream is not None else sys.stderr
    tty = stream.isatty()
    last = [-1]

    def show(done: int, total: int, elapsed_s: float) -> None:
        tenth = 10 * done // total
        if not tty and tenth == last[0]:
            return
        last[0] = tenth
        line = f"frame {done}/{total} ({done / max(elapsed_s, 1e-9):.1f} frames/s)"
        if tty:
            print("\r" + line, end="\n" if done == total else "", file=stream, flush=True)
        else:
            print(line, file=stream, flush=True)

    return show


@dataclass(frozen=True)
class Moment:
    label: str
    time_s: float
    vehicle_id: str
    """The vehicle the frame follows (and whose scan it draws)."""


def key_moments(
    directory: Path, scene: Scene, timeline: Timeline, traj: pd.DataFrame
) -> list[Moment]:
    """The start and end of the default vehicle's time in the scene, the closest
    approach of a follower to its predecessor, and the first split or cut-in."""
    chosen = default_vehicle(scene)
    first, last = timeline.span_s(chosen)
    moments = [Moment("start", first, chosen), Moment("end", last, chosen)]
    begin, end = timeline.times_s[0], timeline.times_s[-1]
    if "gap_to_predecessor_m" in traj:
        gaps = traj.dropna(subset=["gap_to_predecessor_m"])
        gaps = gaps[gaps["time_s"].between(begin, end)]
        if len(gaps):
            row = gaps.loc[gaps["gap_to_predecessor_m"].idxmin()]
            moments.append(Moment(
                f"closest: {row['vehicle_id']} {row['gap_to_predecessor_m']:.1f} m behind "
                f"{row['predecessor_id']}", float(row["time_s"]), str(row["vehicle_id"]),
            ))  # fmt: skip
    events = pd.read_csv(directory / "events.csv", dtype={"vehicle_id": str})
    cohesion = events[
        events["kind"].isin(("split", "cut_in")) & events["time_s"].between(begin, end)
    ]
    if len(cohesion):
        row = cohesion.iloc[0]
        label = f"{str(row['kind']).replace('_', '-')} at {row['vehicle_id']}"
        moments.append(Moment(label, float(row["time_s"]), str(row["vehicle_id"])))
    return sorted(moments, key=lambda m: m.time_s)


#: Width of the filmstrip's square views [m].
FILMSTRIP_WINDOW_M = 80.0


def filmstrip(
    directory: Path, summary: dict[str, Any], traj: pd.DataFrame, path: Path
) -> Path | None:
    """One PNG of the key moments side by side (`key_moments`), drawn like the frames
    of `animate`; None when the run has no scene (older runs, `scene_period_s: null`)
    or no platoon vehicle drove."""
    if not (directory / SCENE_FILE).is_file():
        return None
    scene = read_scene(directory)
    if scene.traffic.empty:
        return None
    timeline = Timeline(scene.traffic)
    moments = key_moments(directory, scene, timeline, traj)
    net = summary.get("network_file")
    plt = figures._plt()
    fig, axes = plt.subplots(1, len(moments), figsize=(3.2 * len(moments), 3.5), squeeze=False)
    fig.subplots_adjust(left=0.005, right=0.995, bottom=0.01, top=0.9, wspace=0.03)
    for k, (ax, moment) in enumerate(zip(axes[0], moments, strict=True)):
        view = FrameView(ax, scene, timeline, Path(net) if net else None, moment.vehicle_id,
                         FILMSTRIP_WINDOW_M, FILMSTRIP_WINDOW_M, legend=k == 0)  # fmt: skip
        view.draw(moment.time_s)
        ax.set_aspect("equal")
        ax.set_title(moment.label, fontsize=8)
    fig.savefig(path, dpi=figures.DPI)
    plt.close(fig)
    return path
