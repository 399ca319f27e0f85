"""Human-driven background traffic: SUMO route files written from the scenario.

Vehicle types and flows become one `.rou.xml`; random trips are generated with SUMO's
own randomTrips.py (SUMO routes each trip when it departs). Files go to the results
folder's `inputs/`, so a run can be repeated from its folder alone.
"""

from __future__ import annotations

import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from platoon_sumo.errors import SumoError
from platoon_sumo.scenario import RunPlan, VehicleTypeConfig
from platoon_sumo.subprocesses import run_tool
from platoon_sumo.sumo.backend import sumo_home

BACKGROUND_TYPE = "background"


def write_traffic_inputs(plan: RunPlan, directory: Path) -> list[Path]:
    """Route files for the scenario's generated demand, in the order SUMO must load them."""
    traffic = plan.scenario.traffic
    sim = plan.scenario.simulation
    directory.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    default_type = BACKGROUND_TYPE if traffic.vehicle_types else "DEFAULT_VEHTYPE"
    if traffic.vehicle_types or traffic.flows:
        root = ET.Element("routes")
        for vt in traffic.vehicle_types:
            root.append(_vtype_element(vt))
        if traffic.vehicle_types:
            ET.SubElement(
                root,
                "vTypeDistribution",
                id=BACKGROUND_TYPE,
                vTypes=" ".join(vt.id for vt in traffic.vehicle_types),
                probabilities=" ".join(repr(vt.probability) for vt in traffic.vehicle_types),
            )
        for i, flow in enumerate(traffic.flows):
            attrs = {
                "id": f"flow{i}",
                "type": flow.type or default_type,
                "begin": repr(flow.begin_s),
                "end": repr(flow.end_s if flow.end_s is not None else sim.end_s),
                # the share that drives as platoons is inserted by platoon-sumo instead
                "vehsPerHour": repr(flow.vehs_per_hour * (1.0 - flow.platoon_share)),
                "from": flow.from_edge,
                "to": flow.to_edge,
                "departLane": "best",
                "departSpeed": "max",
            }
            if flow.via_edges:
                attrs["via"] = " ".join(flow.via_edges)
            ET.SubElement(root, "flow", attrs)
        ET.indent(root)
        path = directory / "traffic.rou.xml"
        ET.ElementTree(root).write(path, encoding="unicode", xml_declaration=True)
        files.append(path)
    if traffic.random_trips is not None:
        files.append(_random_trips(plan, directory, default_type))
    return files


def _vtype_element(vt: VehicleTypeConfig) -> ET.Element:
    attrs = {
        "id": vt.id,
        "vClass": vt.vclass,
        "carFollowModel": vt.car_follow_model,
        "laneChangeModel": vt.lane_change_model,
        "length": repr(vt.length_m),
        "width": repr(vt.width_m),
        "minGap": repr(vt.min_gap_m),
        "maxSpeed": repr(vt.max_speed_mps),
        "accel": repr(vt.accel_mps2),
        "decel": repr(vt.decel_mps2),
        "emergencyDecel": repr(vt.emergency_decel_mps2),
        "sigma": repr(vt.sigma),
        "tau": repr(vt.tau_s),
        "speedFactor": repr(vt.speed_factor),
        "speedDev": repr(vt.speed_dev),
    }
    attrs.update({k: str(v) for k, v in vt.params.items()})
    return ET.Element("vType", attrs)


def _random_trips(plan: RunPlan, directory: Path, type_id: str) -> Path:
    rt = plan.scenario.traffic.random_trips
    assert rt is not None
    sim = plan.scenario.simulation
    out = directory / "random.trips.xml"
    script = Path(sumo_home()) / "tools" / "randomTrips.py"
    cmd = [
        sys.executable, str(script),
        "-n", str(plan.net_file),
        "-o", str(out),
        "-r", str(directory / "random.rou.xml"),  # trips are validated by routing them
        "--begin", repr(rt.begin_s),
        "--end", repr(rt.end_s if rt.end_s is not None else sim.end_s),
        "--period", repr(rt.period_s),
        "--seed", str(rt.seed if rt.seed is not None else sim.seed),
        "--min-distance", repr(rt.min_distance_m),
        "--fringe-factor", repr(rt.fringe_factor),
        "--prefix", "bg",
        "--trip-attributes", f'type="{type_id}" departLane="best" departSpeed="max"',
    ]  # fmt: skip
    env = {**os.environ, "SUMO_HOME": sumo_home()}
    done = run_tool(cmd, env=env, cwd=directory)
    if done.returncode != 0 or not out.is_file():
        raise SumoError(f"randomTrips.py failed: {done.stderr.strip() or done.stdout.strip()}")
    return out
