"""SUMO's jam teleport is a scenario option, off by default: with it, a car stuck
behind stopped cars is teleported (and counted); without it, it waits, and the gridlock
check reports it (not the cars stopped by their schedule)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

STUCK_S = 20.0


def scenario(demand: Path, teleport_s: float | None) -> dict:
    return {
        "simulation": {"step_s": 0.1, "end_s": 120.0, "seed": 1,
                       "time_to_teleport_s": teleport_s},
        "network": {"net_file": str(REPO / "networks" / "straight" / "straight.net.xml")},
        "traffic": {"route_files": [str(demand)]},
        "outputs": {"gridlock_after_s": 30.0},
        "platoons": [{
            "id": "p", "members": 1, "depart_s": 100.0, "route": {"edges": ["WE"]},
            "actuation": "lane", "leader": {"type": "route_following"},
        }],
    }  # fmt: skip


@pytest.mark.parametrize("teleport_s", [None, STUCK_S])
def test_jam_teleports_only_when_the_scenario_asks(
    write_scenario, tmp_path: Path, teleport_s: float | None
) -> None:
    demand = tmp_path / "jam.rou.xml"
    blockers = "\n".join(  # one car parked on every lane at 300 m for the whole run
        f'  <vehicle id="block{lane}" depart="0" departLane="{lane}" departPos="250">'
        f'<route edges="WE"/><stop lane="WE_{lane}" endPos="300" duration="10000"/></vehicle>'
        for lane in (0, 1)
    )
    demand.write_text(
        f'<routes>\n{blockers}\n  <vehicle id="stuck" depart="1"><route edges="WE"/></vehicle>\n'
        "</routes>\n",
        encoding="utf-8",
    )
    out = run(load_plan(write_scenario(scenario(demand, teleport_s))), tmp_path / "out").directory
    summary = json.loads((out / "summary.json").read_text())
    trips = pd.read_csv(out / "tripinfo.csv", sep=";").set_index("tripinfo_id")
    if teleport_s is None:
        assert summary["teleports"] == 0
        assert trips.loc["stuck", "tripinfo_arrival"] < 0  # still waiting at the end
        assert summary["gridlocks"] == 1
        (event,) = summary["gridlock_events"]
        assert event["vehicle_id"] == "stuck" and event["where"].startswith("lane WE_")
        assert 30.0 <= event["time_s"] <= 60.0  # stopped at ~15 s, found at a 10 s check
    else:
        assert summary["teleports"] >= 1
        events = (out / "events.csv").read_text()
        assert "teleport,stuck" in events
