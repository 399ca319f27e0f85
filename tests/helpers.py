"""Paths and small builders shared by the tests."""

from __future__ import annotations

import subprocess
from pathlib import Path

from platoon_sumo.loop.context import StepHook, StepRecord, VehicleRecord

REPO = Path(__file__).resolve().parents[1]
URBAN_GRID_NET = REPO / "networks" / "urban_grid" / "urban_grid.net.xml"
PAPER_WORLD = REPO / "networks" / "paper_world"


def planar_pair_through_b1(depart_s: float, depart_lane: int, end_s: float) -> dict:
    """A scenario: two planar platoon cars (a route-following leader at 8 m/s, a laser
    follower) east through the urban grid's junction B1. SUMO places them and does not
    brake them: only the corridor check (`loop.obstacles`) stops them."""
    return {
        "simulation": {"step_s": 0.1, "end_s": end_s, "seed": 1},
        "network": {"net_file": str(URBAN_GRID_NET)},
        "platoons": [{
            "id": "p", "members": 2, "spacing_m": 10.0, "depart_s": depart_s,
            "depart_lane": depart_lane, "actuation": "planar",
            "route": {"edges": ["A1B1", "B1C1", "C1right1"]},
            "leader": {"type": "route_following", "params": {"cruise_speed_mps": 8.0}},
            "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"}},
        }],
    }  # fmt: skip


def build_net(
    folder: Path, nodes: str, edges: str, connections: str | None = None, *options: str
) -> Path:
    """`folder/x.net.xml` built by netconvert from plain XML node, edge and (optional)
    connection files written beside it."""
    from platoon_sumo.sumo.backend import sumo_binary

    (folder / "x.nod.xml").write_text(nodes, encoding="utf-8")
    (folder / "x.edg.xml").write_text(edges, encoding="utf-8")
    net = folder / "x.net.xml"
    cmd = [sumo_binary("netconvert"), "-n", str(folder / "x.nod.xml"),
           "-e", str(folder / "x.edg.xml"), "-o", str(net), *options]  # fmt: skip
    if connections is not None:
        (folder / "x.con.xml").write_text(connections, encoding="utf-8")
        cmd += ["-x", str(folder / "x.con.xml")]
    subprocess.run(cmd, check=True, capture_output=True)
    return net


def add_standing_car(vehicle_id: str, edges: list[str], width_m: float, depart_lane: str,
                     depart_pos: str) -> None:  # fmt: skip
    """Insert a SUMO car of `width_m` on `edges` that obeys only TraCI (no speed or
    lane-change checks of its own): a test hook then stands it where it wants."""
    import libsumo

    libsumo.route.add(f"{vehicle_id}_route", edges)
    libsumo.vehicletype.copy("DEFAULT_VEHTYPE", f"{vehicle_id}_type")
    libsumo.vehicletype.setWidth(f"{vehicle_id}_type", width_m)
    libsumo.vehicle.add(vehicle_id, f"{vehicle_id}_route", typeID=f"{vehicle_id}_type",
                        depart="now", departLane=depart_lane, departPos=depart_pos)  # fmt: skip
    libsumo.vehicle.setSpeedMode(vehicle_id, 0)
    libsumo.vehicle.setLaneChangeMode(vehicle_id, 0)


class KeptByTheLeader(StepHook):
    """A SUMO car (`add_standing_car`) on lane `lane` of `edge`, inserted when the
    platoon car `leader_id` is first seen and put every step where `where` says, at the
    leader's speed, facing east, until `until_s`, then removed. `state`: "waiting",
    "there", "gone"."""

    def __init__(self, car_id: str, edge: str, lane: int, leader_id: str, until_s: float):
        self.car_id, self.edge, self.lane = car_id, edge, lane
        self.leader_id, self.until_s = leader_id, until_s
        self.state = "waiting"

    def where(self, leader: VehicleRecord) -> tuple[float, float]:
        """Where the car stands this step (front bumper x, y) [m]."""
        raise NotImplementedError

    def on_step(self, record: StepRecord) -> None:
        import libsumo

        leader = next((v for v in record.vehicles if v.id == self.leader_id), None)
        if leader is None or self.state == "gone":
            return
        if self.state == "waiting":
            add_standing_car(self.car_id, [self.edge], 1.8, str(self.lane), "0")
            self.state = "there"
        if record.time_s >= self.until_s:
            libsumo.vehicle.remove(self.car_id)
            self.state = "gone"
            return
        x, y = self.where(leader)
        libsumo.vehicle.moveToXY(self.car_id, self.edge, self.lane, x, y, 90.0, keepRoute=1)
        libsumo.vehicle.setPreviousSpeed(self.car_id, leader.speed_mps)
