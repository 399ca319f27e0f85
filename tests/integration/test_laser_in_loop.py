"""The co-simulation hands each equipped vehicle an exact scan of the SUMO world."""

from __future__ import annotations

import math

import numpy as np

from platoon_sumo.loop.context import RunContext, RunOutcome, StepRecord
from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET


def scenario_with_laser() -> dict:
    """A SUMO car stops at A1's red light; our equipped car approaches and stops behind it."""
    return {
        "simulation": {"step_s": 0.1, "end_s": 40.0, "seed": 1},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "traffic": {
            "vehicle_types": [{"id": "human", "sigma": 0.0}],
            "flows": [
                {"from_edge": "left1A1", "to_edge": "C1right1", "vehs_per_hour": 3600,
                 "begin_s": 0.0, "end_s": 1.0, "type": "human"}
            ],
        },
        "platoons": [
            {"id": "ego", "route": {"edges": ["left1A1", "A1B1", "B1C1", "C1right1"]},
             "depart_s": 4.0, "depart_lane": 0,
             "leader": {"type": "route_following", "params": {"cruise_speed_mps": 8.0},
                        "sensor": {"preset": "utm30lx"}}}
        ],
    }  # fmt: skip


class ForwardRayVsTruth:
    """Compares the forward ray of each scan with the gap in the world it was taken in."""

    def __init__(self) -> None:
        self.pairs: list[tuple[float, float]] = []
        self.scan_count = 0

    def on_start(self, run: RunContext) -> None:
        pass

    def on_end(self, outcome: RunOutcome) -> None:
        pass

    def on_step(self, record: StepRecord) -> None:
        w = record.sensed_world
        if w is None or not record.vehicles:
            return
        ego = record.vehicles[0]
        scan = ego.scan
        if scan is None or w.time_s != scan.stamp_s:
            return
        self.scan_count += 1
        forward = scan.ranges[round(-scan.angle_min / scan.angle_increment)]
        others = [vid for vid in w.ids if vid != ego.id]
        if not others or not math.isfinite(forward):
            return
        i = w.index[others[0]]
        rear = np.array([w.front_x_m[i], w.front_y_m[i]]) - w.length_m[i] * np.array(
            [math.cos(w.yaw_rad[i]), math.sin(w.yaw_rad[i])]
        )
        truth = float(np.hypot(rear[0] - scan.origin_x_m, rear[1] - scan.origin_y_m))
        self.pairs.append((forward, truth))


def test_forward_ray_measures_the_true_bumper_gap(write_scenario, tmp_path):
    watcher = ForwardRayVsTruth()
    result = run(load_plan(write_scenario(scenario_with_laser())), tmp_path / "out", [watcher])
    assert result.summary["collisions"] == 0
    assert watcher.scan_count > 100  # 40 Hz sensor, 10 Hz steps: a fresh scan every step
    measured, truth = np.array(watcher.pairs).T
    assert len(measured) > 50
    assert truth.min() < 5.0 < 25.0 < truth.max()  # approached from far to standstill
    assert np.abs(measured - truth).max() < 1e-6


def test_scan_command_draws_the_scan_as_png(write_scenario, tmp_path, capsys):
    import matplotlib.image

    from platoon_sumo.cli import main

    scenario = write_scenario(scenario_with_laser())
    png = tmp_path / "scan.png"
    assert main(["scan", str(scenario), "--at", "20", "--out", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    pixels = matplotlib.image.imread(png)
    assert pixels.shape[0] > 500 and pixels.shape[1] > 500
    assert pixels[..., :3].std() > 0.05  # not a blank canvas
    assert "scan written" in capsys.readouterr().out


def test_scan_command_without_sensor_explains_what_to_do(write_scenario, tmp_path, capsys):
    from platoon_sumo.cli import main

    data = scenario_with_laser()
    del data["platoons"][0]["leader"]["sensor"]
    code = main(["scan", str(write_scenario(data)), "--at", "10", "--out", str(tmp_path / "x.png")])
    assert code == 2
    err = capsys.readouterr().err
    assert "no laser scan" in err and "give the platoon a sensor" in err


class ScanStamps:
    def __init__(self) -> None:
        self.stamps: list[float] = []
        self.ranges: list[np.ndarray] = []

    def on_start(self, run: RunContext) -> None:
        pass

    def on_end(self, outcome: RunOutcome) -> None:
        pass

    def on_step(self, record: StepRecord) -> None:
        for v in record.vehicles:
            if v.scan is not None and (not self.stamps or self.stamps[-1] != v.scan.stamp_s):
                self.stamps.append(v.scan.stamp_s)
                self.ranges.append(v.scan.ranges)


def test_scans_come_at_the_sensor_rate_and_noise_is_seeded(write_scenario, tmp_path):
    data = scenario_with_laser()
    data["simulation"]["end_s"] = 12.0
    data["platoons"][0]["leader"]["sensor"]["overrides"] = {"rate_hz": 5.0, "noise_std_m": 0.02}
    path = write_scenario(data)
    first, again, other_seed = ScanStamps(), ScanStamps(), ScanStamps()
    run(load_plan(path), tmp_path / "a", [first])
    assert len(first.stamps) > 20
    assert np.allclose(np.diff(first.stamps), 0.2)  # 5 Hz with 0.1 s steps: every 2nd step
    run(load_plan(path), tmp_path / "b", [again])
    run(load_plan(path, seed=99), tmp_path / "c", [other_seed])
    same = [
        np.array_equal(a, b, equal_nan=True)
        for a, b in zip(first.ranges, again.ranges, strict=True)
    ]
    assert all(same)  # the same seed gives the same noisy scans
    differ = [
        not np.array_equal(a, b, equal_nan=True)
        for a, b in zip(first.ranges, other_seed.ranges, strict=False)
    ]
    assert any(differ)  # and the noise is really there
