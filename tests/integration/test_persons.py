"""Persons and bicycles in the demand are not human-driven vehicle trips: SUMO writes
persons to personinfo.csv, and the summary counts both apart from the cars."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

CARS, PEDESTRIANS, BIKES = 3, 4, 2


def test_persons_are_reported_apart_from_human_vehicles(write_scenario, tmp_path: Path) -> None:
    demand = tmp_path / "demand.rou.xml"
    cars = [
        (2.0 * k, f'  <vehicle id="car{k}" depart="{2 * k}"><route edges="WE"/></vehicle>')
        for k in range(CARS)
    ]
    walkers = [
        (k + 0.5, f'  <person id="walker{k}" depart="{k + 0.5}" departPos="{50 + 10 * k}">'
         f'<walk edges="WE" arrivalPos="{120 + 10 * k}"/></person>')
        for k in range(PEDESTRIANS)
    ]  # fmt: skip
    bikes = [
        (3.0 * k + 0.2, f'  <vehicle id="bike{k}" type="bike" depart="{3 * k + 0.2}">'
         '<route edges="WE"/></vehicle>')
        for k in range(BIKES)
    ]  # fmt: skip
    lines = [line for _, line in sorted(cars + walkers + bikes)]  # by depart time for SUMO
    demand.write_text(
        '<routes>\n  <vType id="bike" vClass="bicycle"/>\n' + "\n".join(lines) + "\n</routes>\n",
        encoding="utf-8",
    )
    scenario = {
        "simulation": {"step_s": 0.1, "end_s": 200.0, "seed": 2},
        "network": {"net_file": str(REPO / "networks" / "straight" / "straight.net.xml")},
        "traffic": {"route_files": [str(demand)]},
        "platoons": [{
            "id": "p", "members": 2, "spacing_m": 8.0, "depart_s": 20.0,
            "route": {"edges": ["WE"]}, "actuation": "lane",
            "leader": {"type": "route_following"}, "follower": {"type": "route_following"},
        }],
    }  # fmt: skip
    out = run(load_plan(write_scenario(scenario)), tmp_path / "out").directory
    traffic = json.loads((out / "summary.json").read_text())["traffic"]

    assert traffic["human_trips"] == CARS  # cars only: no platoon, bicycle or person
    assert traffic["other_trips"] == {"bicycle": BIKES}
    assert traffic["persons"] == PEDESTRIANS
    assert traffic["persons_finished"] == PEDESTRIANS
    assert 10.0 < traffic["person_mean_travel_time_s"] < 200.0  # 70 m at walking pace
    trips = pd.read_csv(out / "tripinfo.csv", sep=";")
    assert not trips["tripinfo_id"].str.startswith("walker").any()
    persons = pd.read_csv(out / "personinfo.csv", sep=";")
    assert sorted(persons["personinfo_id"]) == [f"walker{k}" for k in range(PEDESTRIANS)]
