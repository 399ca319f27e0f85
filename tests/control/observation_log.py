"""Recorded laser-follower observations: a compact file format, its loader and the
recorder that writes it from a real closed-loop run.

A log holds, per recorded follower, its parameters and the Observations it got, step by
step, so they can be replayed through the reference and the fast follower
(``test_laser_follower_equivalence.py``, ``tools/bench_controllers.py``). It stores
plain numbers and arrays (no pickled package classes), lzma-compressed:

- per vehicle: the parameters (a nested dict for ``load_dataclass``), the limits, the
  scan geometry, and per step the scalars of the Observation, the index of its route
  path, the index of its scan (-1: none; a repeated index is the same scan object, as
  the loop hands it) and the signal ahead (for the route-following fallback);
- per scan: origin, heading, stamp and the ranges as float32 (the replay feeds both
  followers the same float64 values widened from them; float32 keeps the files small);
- per route path: its arrays and lane changes.

``vehicle_ahead``, ``link_ahead`` and ``lane_change`` are not stored: the laser
follower never reads them (its fallback gets ``vehicle_ahead=None``).

Recording (from the repository root; SUMO runs, a minute or two each)::

    python -m tests.control.observation_log urban   # tests/control/data/urban_platoon.obs.xz
    python -m tests.control.observation_log city    # tests/control/data/city_platoons.obs.xz
    python -m tests.control.observation_log robot   # tests/control/data/robot_world.obs.xz

Each copies a shipped scenario with its followers replaced by ``RecordingLaserFollower``
(named by its dotted path), runs it for a while and keeps a window of steps per follower.
"""

from __future__ import annotations

import argparse
import dataclasses
import lzma
import pickle
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from platoon_sumo.config_loader import load_dataclass
from platoon_sumo.control.base import Command, Observation
from platoon_sumo.control.laser_follower import LaserFollower, LaserFollowerParams
from platoon_sumo.path import LaneChange, RoutePath
from platoon_sumo.sensors.laser import LaserScan
from platoon_sumo.vehicles import MotionLimits
from platoon_sumo.world import SignalAhead

REPO = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data"
FORMAT = 1

_SCALARS = (
    "time_s",
    "dt_s",
    "x_m",
    "y_m",
    "yaw_rad",
    "speed_mps",
    "front_offset_m",
    "length_m",
    "width_m",
    "lane_offset_m",
)
_SCAN_META = ("angle_min", "angle_max", "angle_increment", "scan_time", "range_min", "range_max")


@dataclasses.dataclass
class FollowerLog:
    """One follower's replayable run."""

    vehicle_id: str
    params: LaserFollowerParams
    observations: list[Observation]


# ----------------------------------------------------------------------------- recording

_RECORDED: dict[str, tuple[LaserFollowerParams, list[Observation]]] = {}


class RecordingLaserFollower(LaserFollower):
    """A ``laser_follower`` that keeps every Observation it gets (in ``_RECORDED``)."""

    def step(self, observation: Observation) -> Command:
        _RECORDED.setdefault(observation.vehicle_id, (self.params, []))[1].append(observation)
        return super().step(observation)


def _encode(
    runs: dict[str, tuple[LaserFollowerParams, list[Observation]]],
) -> dict[str, Any]:
    paths: list[RoutePath] = []
    path_ids: dict[int, int] = {}
    scans: list[LaserScan] = []
    vehicles = []
    for vid, (params, observations) in runs.items():
        scan_ids: dict[int, int] = {}
        scan_index, path_index, signals = [], [], []
        for obs in observations:
            if id(obs.path) not in path_ids:
                path_ids[id(obs.path)] = len(paths)
                paths.append(obs.path)
            path_index.append(path_ids[id(obs.path)])
            if obs.scan is None:
                scan_index.append(-1)
            else:
                if id(obs.scan) not in scan_ids:
                    scan_ids[id(obs.scan)] = len(scans)
                    scans.append(obs.scan)
                scan_index.append(scan_ids[id(obs.scan)])
            sig = obs.signal
            signals.append(
                None
                if sig is None
                else (sig.tls_id, sig.link_index, sig.state, float(sig.distance_m))
            )
        first = observations[0]
        geometry = next((s for s in scans if s is not None), None)
        vehicles.append(
            {
                "vehicle_id": vid,
                "role": first.role,
                "params": dataclasses.asdict(params),
                "limits": dataclasses.asdict(first.limits),
                "scalars": {
                    k: np.array([getattr(o, k) for o in observations], dtype=np.float64)
                    for k in _SCALARS
                },
                "path": np.array(path_index, dtype=np.int32),
                "scan": np.array(scan_index, dtype=np.int32),
                "signal": signals,
                "scan_meta": {k: float(getattr(geometry, k)) for k in _SCAN_META}
                if geometry is not None
                else None,
            }
        )
    return {
        "format": FORMAT,
        "vehicles": vehicles,
        "paths": [
            {
                "xy_m": p.xy_m,
                "spacing_m": p.spacing_m,
                "speed_limit_mps": p.speed_limit_mps,
                "lane_index": p.lane_index,
                "lane_ids": p.lane_ids,
                "lane_width_m": p.lane_width_m,
                "lane_changes": [dataclasses.astuple(c) for c in p.lane_changes],
            }
            for p in paths
        ],
        "scans": {
            "ranges": np.array([s.ranges for s in scans], dtype=np.float32).reshape(len(scans), -1),
            "pose": np.array(
                [(s.origin_x_m, s.origin_y_m, s.heading_rad, s.stamp_s) for s in scans],
                dtype=np.float64,
            ).reshape(-1, 4),
        },
    }


def save(runs: dict[str, tuple[LaserFollowerParams, list[Observation]]], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with lzma.open(path, "wb", preset=9 | lzma.PRESET_EXTREME) as f:
        pickle.dump(_encode(runs), f, protocol=pickle.HIGHEST_PROTOCOL)


# ----------------------------------------------------------------------------- loading


def load(path: Path) -> list[FollowerLog]:
    """The followers of a log, with their Observations rebuilt (scans shared as recorded)."""
    with lzma.open(path, "rb") as f:
        data = pickle.load(f)  # our own test fixture
    if data["format"] != FORMAT:
        raise ValueError(f"{path}: log format {data['format']}, expected {FORMAT}")
    paths = [
        RoutePath(
            xy_m=np.asarray(p["xy_m"], dtype=np.float64),
            spacing_m=float(p["spacing_m"]),
            speed_limit_mps=np.asarray(p["speed_limit_mps"], dtype=np.float64),
            lane_index=np.asarray(p["lane_index"], dtype=np.int64),
            lane_ids=tuple(p["lane_ids"]),
            lane_width_m=np.asarray(p["lane_width_m"], dtype=np.float64),
            lane_changes=tuple(
                LaneChange(c[0], c[1], tuple(c[2]), c[3]) for c in p["lane_changes"]
            ),
        )
        for p in data["paths"]
    ]
    ranges = data["scans"]["ranges"].astype(np.float64)
    poses = data["scans"]["pose"]
    out = []
    for v in data["vehicles"]:
        params = load_dataclass(LaserFollowerParams, v["params"], str(path))
        limits = MotionLimits(**v["limits"])
        meta = v["scan_meta"]
        scans: dict[int, LaserScan] = {}
        observations = []
        sc = v["scalars"]
        for i in range(len(v["path"])):
            k = int(v["scan"][i])
            scan = None
            if k >= 0:
                if k not in scans:
                    ox, oy, heading, stamp = (float(q) for q in poses[k])
                    scans[k] = LaserScan(
                        **meta,
                        time_increment=0.0,
                        ranges=ranges[k],
                        origin_x_m=ox,
                        origin_y_m=oy,
                        heading_rad=heading,
                        stamp_s=stamp,
                    )
                scan = scans[k]
            sig = v["signal"][i]
            scalars: dict[str, Any] = {name: float(sc[name][i]) for name in _SCALARS}
            observations.append(
                Observation(
                    **scalars,
                    vehicle_id=v["vehicle_id"],
                    role=v["role"],
                    limits=limits,
                    path=paths[int(v["path"][i])],
                    signal=None if sig is None else SignalAhead(*sig),
                    scan=scan,
                )
            )
        out.append(FollowerLog(v["vehicle_id"], params, observations))
    return out


def logs() -> Iterator[Path]:
    """The recorded logs shipped with the tests."""
    return iter(sorted(DATA.glob("*.obs.xz")))


# ----------------------------------------------------------------------------- scenarios

RECORDER = f"{__name__}:RecordingLaserFollower"

ROBOT_PARAMS = {  # the module docstring's robot scale
    "standstill_gap_m": 0.35,
    "time_gap_s": 0.6,
    "min_gap_m": 0.15,
    "comfort_decel_mps2": 0.5,
    "lookahead_min_m": 0.3,
    "trail_spacing_m": 0.02,
    "perception": {"break_abs_m": 0.03, "corner_abs_m": 0.01},
    "tracker": {
        "accel_noise_mps2": 1.0,
        "meas_noise_m": 0.01,
        "start_range_max_m": 1.5,
        "start_lateral_m": 0.2,
        "init_speed_std_mps": 0.3,
    },
    "fallback": {"lookahead_min_m": 0.3, "comfort_decel_mps2": 0.5, "cruise_speed_mps": 0.3},
}


def _urban(sc: dict[str, Any]) -> None:
    sc["platoons"][0]["follower"]["type"] = RECORDER


def _city(sc: dict[str, Any]) -> None:
    """The first platoon (west) as the log was recorded: lane actuation on the repaired
    district (the scenario now runs the district as shipped, with sublane actuation)."""
    sc["platoons"] = sc["platoons"][:1]
    sc["platoons"][0]["follower"]["type"] = RECORDER
    sc["platoons"][0]["actuation"] = "lane"
    sc["simulation"]["lateral_resolution_m"] = None
    sc["network"]["net_file"] = str(REPO / "networks" / "drt_city" / "drt_city.net.xml.gz")
    for vtype in sc["traffic"]["vehicle_types"]:
        vtype["lane_change_model"] = "LC2013"  # without the sublane model


def _robot(sc: dict[str, Any]) -> None:
    platoon = sc["platoons"][0]
    platoon["follower"] = {
        "type": RECORDER,
        "params": {**ROBOT_PARAMS, "on_lost": "route_following"},
        # paper_follower-like, a little wider and farther (the docstring's 0.3..1-3 m)
        "sensor": {"preset": "paper_follower", "overrides": {"range_max_m": 2.0}},
    }


# name: (scenario, edit, end_s, (first, last) time kept [s], every n-th follower kept)
SCENARIOS: dict[str, tuple[str, Any, float, tuple[float, float], int]] = {
    "urban": ("urban_platoon.yaml", _urban, 120.0, (0.0, 120.0), 2),
    "city": ("city_platoons.yaml", _city, 260.0, (0.0, 260.0), 1),
    "robot": ("paper_world.yaml", _robot, 125.0, (104.0, 122.0), 2),
}


def _absolute(sc: dict[str, Any], base: Path) -> None:
    net = sc["network"]
    for key in ("net_file", "sumocfg"):
        if key in net and not str(net[key]).startswith("sumo:"):
            net[key] = str((base / net[key]).resolve())
    if "additional_files" in net:
        net["additional_files"] = [str((base / f).resolve()) for f in net["additional_files"]]
    sc.pop("outputs", None)


def record(
    name: str, out: Path, window: tuple[float, float] | None = None, stride: int | None = None
) -> Path:
    from platoon_sumo import runner

    file, edit, end_s, default_window, default_stride = SCENARIOS[name]
    t0, t1 = window or default_window
    stride = stride or default_stride
    src = REPO / "scenarios" / file
    sc = yaml.safe_load(src.read_text())
    _absolute(sc, src.parent)
    edit(sc)
    _RECORDED.clear()
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / file
        copy.write_text(yaml.safe_dump(sc, sort_keys=False))
        runner.run(runner.load_plan(copy, end_s=end_s), out_dir=Path(tmp) / "results")
    # every `stride`-th follower, the steps within the window (a replay starts with a
    # fresh follower there: it picks up the predecessor within a few scans)
    runs = {
        vid: (params, [o for o in observations if t0 <= o.time_s <= t1])
        for vid, (params, observations) in sorted(_RECORDED.items())[::stride]
    }
    save(runs, out)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Record laser-follower observations.")
    parser.add_argument("scenario", choices=sorted(SCENARIOS))
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--stride", type=int, default=None, help="keep every n-th follower")
    parser.add_argument(
        "--window", type=float, nargs=2, default=None, help="first and last time kept [s]"
    )
    args = parser.parse_args(argv)
    default = {"urban": "urban_platoon", "city": "city_platoons", "robot": "robot_world"}
    out = args.out or DATA / f"{default[args.scenario]}.obs.xz"
    record(args.scenario, out, args.window, args.stride)
    size = out.stat().st_size
    for log in load(out):
        print(f"{log.vehicle_id}: {len(log.observations)} steps")
    print(f"wrote {out} ({size / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
