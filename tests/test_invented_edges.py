"""`validate` names what netconvert made up on a platoon's route: a guessed ramp, a
joined junction crossed on long internal lanes."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from platoon_sumo.cli import main
from platoon_sumo.sumo import network
from platoon_sumo.sumo.network import Network
from tests.helpers import build_net


def netconvert(tmp_path: Path, nodes: str, edges: str, *options: str) -> Path:
    return build_net(tmp_path, f"<nodes>{nodes}</nodes>", f"<edges>{edges}</edges>", None, *options)


def scenario(tmp_path: Path, net: Path, routes: dict[str, list[str]]) -> Path:
    data = {
        "simulation": {"end_s": 5},
        "network": {"net_file": str(net)},
        "platoons": [{"id": pid, "route": {"edges": edges}} for pid, edges in routes.items()],
    }
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_a_route_over_a_guessed_ramp_is_named(tmp_path, capfd):
    # a one-lane ramp joins a two-lane motorway that keeps two lanes: netconvert adds
    # an acceleration lane on an edge of its own
    net = netconvert(
        tmp_path,
        '<node id="A" x="0" y="0"/><node id="B" x="500" y="0"/><node id="C" x="1000" y="0"/>'
        '<node id="R" x="200" y="-150"/>',
        '<edge id="AB" from="A" to="B" numLanes="2" speed="33.3"/>'
        '<edge id="BC" from="B" to="C" numLanes="2" speed="33.3"/>'
        '<edge id="RB" from="R" to="B" numLanes="1" speed="22.0"/>',
        "--ramps.guess",
    )
    path = scenario(tmp_path, net, {"merge": ["RB", "BC-AddedOnRampEdge", "BC"],
                                    "again": ["RB", "BC-AddedOnRampEdge", "BC"]})  # fmt: skip
    assert main(["validate", str(path)]) == 0
    out, err = capfd.readouterr()
    assert "OK" in out
    (line,) = err.splitlines()  # once, naming every platoon that meets it
    assert line.startswith(
        f"warning: {path}: route of platoon 'merge', 'again': edge 'BC-AddedOnRampEdge'"
    )
    assert "--ramps.guess" in line


CROSSROADS = (
    '<node id="W" x="-300" y="0"/><node id="J1" x="0" y="0"/><node id="J2" x="8" y="0"/>'
    '<node id="E" x="300" y="0"/><node id="S" x="4" y="-300"/><node id="N" x="4" y="300"/>',
    '<edge id="WJ" from="W" to="J1" numLanes="2"/><edge id="JJ" from="J1" to="J2" numLanes="2"/>'
    '<edge id="JE" from="J2" to="E" numLanes="2"/><edge id="SJ" from="S" to="J1" numLanes="2"/>'
    '<edge id="JN" from="J2" to="N" numLanes="2"/>',
)


def test_a_joined_junction_is_named_where_the_crossing_is_long(tmp_path, monkeypatch):
    # the two junctions joined into one cluster (what --junctions.join does to close ones)
    nodes, edges = CROSSROADS
    net = Network(netconvert(tmp_path, nodes + '<join nodes="J1 J2"/>', edges))
    route = ["WJ", "JE"]
    assert net.invented_on_route(route) == []  # a 22 m crossing: nothing to say
    monkeypatch.setattr(network, "LONG_JOINED_CROSSING_M", 1.0)
    (message,) = net.invented_on_route(route)
    assert message.startswith("junction 'cluster_J1_J2' between 'WJ' and 'JE' was joined")
    assert "on 22 m of internal lanes" in message


def test_unjoined_junctions_are_not_named(tmp_path, monkeypatch):
    net = Network(netconvert(tmp_path, *CROSSROADS))
    monkeypatch.setattr(network, "LONG_JOINED_CROSSING_M", 0.0)
    assert net.invented_on_route(["WJ", "JJ", "JE"]) == []


@pytest.mark.parametrize("route", [["WJ", "JJ", "JE"]])
def test_a_plain_network_validates_without_warnings(tmp_path, capfd, route):
    path = scenario(tmp_path, netconvert(tmp_path, *CROSSROADS), {"p": route})
    assert main(["validate", str(path)]) == 0
    assert capfd.readouterr().err == ""
