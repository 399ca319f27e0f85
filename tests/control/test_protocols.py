"""Issue 13 acceptance: the laser follower runs every disturbance protocol of
`scenarios/protocols/` with a noisy laser (3 cm range noise, 1 % dropouts), through SUMO.

The protocol files ship with `cacc` followers; here the follower block is swapped for
the laser-only follower on the automotive lidar preset, as `tools/baselines.py` does
for the comparison table (docs/baselines.md).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

pytestmark = pytest.mark.slow  # `pytest -m "not slow"` leaves this module out

PROTOCOLS = sorted((REPO / "scenarios" / "protocols").glob("*.yaml"))
NOISY_LIDAR = {"preset": "lidar_120m", "overrides": {"noise_std_m": 0.03, "dropout_prob": 0.01}}


def _noisy_laser_run(protocol: Path, folder: Path) -> Path:
    doc = yaml.safe_load(protocol.read_text())
    doc["network"]["net_file"] = str((protocol.parent / doc["network"]["net_file"]).resolve())
    traffic = doc.get("traffic", {})
    traffic["route_files"] = [str(protocol.parent / f) for f in traffic.get("route_files", [])]
    (platoon,) = doc["platoons"]
    platoon["leader"].pop("sensors", None)  # no V2V: the laser follower needs none
    platoon["follower"] = {
        "type": "laser_follower",
        "params": {"time_gap_s": 1.2, "standstill_gap_m": 2.0},
        "sensor": NOISY_LIDAR,
    }
    doc["outputs"]["directory"] = str(folder / "out")
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc))
    run(load_plan(path))
    return folder / "out"


def test_every_protocol_is_covered() -> None:
    assert {p.stem for p in PROTOCOLS} >= {"sinusoid", "braking", "stop_and_go", "cut_in"}


@pytest.mark.parametrize("protocol", PROTOCOLS, ids=lambda p: p.stem)
def test_laser_follower_runs_the_protocol_with_a_noisy_laser(
    protocol: Path, tmp_path: Path
) -> None:
    out = _noisy_laser_run(protocol, tmp_path)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "complete"
    assert summary["collisions"] == 0, summary["collision_events"]
    assert summary["sumo_collisions_with_platoons"] == 0
    t = pd.read_csv(out / "trajectories.csv")
    start = float(yaml.safe_load(protocol.read_text())["outputs"]["metrics_start_s"])
    disturbed = t[(t.time_s >= start) & (t.member_index > 0)]
    assert disturbed.vehicle_id.nunique() == 7  # the whole platoon is still on the road
    assert disturbed.gap_to_predecessor_m.min() > 1.5
    last = t[t.time_s == t.time_s.max()]
    assert (last[last.member_index > 0].controller_mode == "following").all()
    if protocol.stem == "cut_in":
        # the car that cut in was followed as the vehicle ahead, then left: every
        # follower has its own predecessor back by the end
        assert summary["platoon_events"]["cut_ins"] >= 1
        assert last[last.member_index > 0].predecessor_in_view.all()
        return
    # every follower tracks its predecessor throughout (1 % dropouts do not break it)
    assert (disturbed.controller_mode == "following").all()
    assert disturbed.predecessor_in_view.mean() > 0.99
    # the disturbance is not amplified down the platoon (acceleration l2 gains)
    window = t[t.time_s >= start]
    norms = window.groupby("member_index").accel_mps2.apply(lambda a: np.sqrt((a**2).sum()))
    gains = norms.to_numpy()[1:] / norms.to_numpy()[:-1]
    assert gains.max() < 1.0, gains
