"""Cars queued at a light that never turns green are a queue, not a gridlock, whether
the gridlock check falls in its red or its yellow phase."""

from __future__ import annotations

import json

from platoon_sumo.runner import load_plan, run
from tests.helpers import URBAN_GRID_NET

#: A1 cycles red (40 s) and yellow (20 s) for every approach, never green.
NEVER_GREEN = """<additional>
  <tlLogic id="A1" type="static" programID="never_green" offset="0">
    <phase duration="40" state="rrrrrrrrrrrrrrrr"/>
    <phase duration="20" state="yyyyyyyyyyyyyyyy"/>
  </tlLogic>
</additional>
"""


def test_cars_waiting_at_a_light_without_green_are_not_gridlocked(write_scenario, tmp_path):
    program = tmp_path / "never_green.add.xml"
    program.write_text(NEVER_GREEN, encoding="utf-8")
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 200.0, "seed": 1},
        "network": {"net_file": str(URBAN_GRID_NET), "additional_files": [str(program)]},
        "traffic": {"flows": [{"from_edge": "left1A1", "to_edge": "A1B1",
                               "vehs_per_hour": 600, "begin_s": 0.0, "end_s": 30.0}]},
        "outputs": {"gridlock_after_s": 30.0},
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    assert summary["all_vehicles"]["departed"] >= 3  # a queue formed at A1 and stayed
    assert summary["all_vehicles"]["arrived"] == 0
    # 17 gridlock checks from 30 s on, about a third of them in a yellow phase
    assert summary["gridlocks"] == 0
