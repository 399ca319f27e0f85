"""`vehicle.sumo_speed_factor`: with lane actuation SUMO caps a platoon car's speed at its
speed factor times the lane's limit, whatever the controller commands."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

LIMIT_MPS = 27.78  # networks/straight: 100 km/h


def _top_speeds(folder: Path, factor: str) -> pd.Series:
    path = folder / "scenario.yaml"
    path.write_text(
        textwrap.dedent(f"""\
        simulation: {{step_s: 0.1, end_s: 40, seed: 2}}
        network: {{net_file: {REPO / "networks/straight/straight.net.xml"}}}
        platoons:
          - id: p
            route: {{edges: [WE]}}
            members: 6
            spacing_m: 10.0
            actuation: lane
            vehicle: {{max_speed_mps: 40.0, max_accel_mps2: 3.0, sumo_speed_factor: {factor}}}
            leader:
              type: speed_profile
              params: {{profile: constant, cruise_speed_mps: 35.0}}
            follower:
              type: acc
              params: {{time_gap_s: 1.0}}
              sensors: [{{type: radar}}]
        outputs: {{directory: {folder / "out"}}}
        """)
    )
    run(load_plan(path))
    t = pd.read_csv(folder / "out" / "trajectories.csv")
    return t.groupby("vehicle_id").speed_mps.max()


@pytest.mark.parametrize("factor", [1.0, 0.9])
def test_every_member_is_capped_at_the_same_factor_of_the_limit(tmp_path, factor):
    top = _top_speeds(tmp_path, str(factor))
    assert top.max() == pytest.approx(factor * LIMIT_MPS, abs=0.01)
    assert top.min() > factor * LIMIT_MPS - 0.5  # every follower reached it too


def test_without_a_factor_sumo_draws_one_per_member(tmp_path):
    top = _top_speeds(tmp_path, "null")
    assert top.max() - top.min() > 0.5  # caps differ between members
