"""tools/osm_to_net.py on small OpenStreetMap files: a race circuit becomes a drivable
network; a file without car roads fails clearly and writes nothing."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import sumolib

from tests.helpers import REPO

TOOL = REPO / "tools" / "osm_to_net.py"


def osm(path: Path, highway: str) -> Path:
    """A closed loop of about 1.2 km (a square of 300 m sides) of one highway type."""
    corners = [(52.0, 13.0), (52.0, 13.0044), (52.0027, 13.0044), (52.0027, 13.0)]
    nodes = "\n".join(
        f'  <node id="{k + 1}" lat="{lat}" lon="{lon}" version="1"/>'
        for k, (lat, lon) in enumerate(corners)
    )
    path.write_text(
        f"""<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6" generator="test">
{nodes}
  <way id="10" version="1">
    <nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
    <tag k="highway" v="{highway}"/>
  </way>
</osm>
""",
        encoding="utf-8",
    )
    return path


def convert(src: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(TOOL), str(src), "-o", str(out)],
        capture_output=True, text=True, check=False, cwd=REPO,
    )  # fmt: skip


def test_a_race_circuit_becomes_a_network_cars_may_drive(tmp_path: Path) -> None:
    out = tmp_path / "ring.net.xml"
    done = convert(osm(tmp_path / "ring.osm", "raceway"), out)
    assert done.returncode == 0, done.stderr
    net = sumolib.net.readNet(str(out))
    drivable = [e for e in net.getEdges() if e.allows("passenger")]
    assert drivable and sum(e.getLength() for e in drivable) > 1000.0  # the whole loop
    assert f"({len(drivable)} edges a car may use)" in done.stdout
    assert not list(tmp_path.glob(".osm_to_net_*"))  # no temporary left behind


@pytest.mark.parametrize("highway", ["footway", "cycleway"])
def test_no_car_roads_fail_clearly_and_keep_an_existing_output(
    tmp_path: Path, highway: str
) -> None:
    out = tmp_path / "mine.net.xml"
    out.write_text("the user's own file\n")
    done = convert(osm(tmp_path / "paths.osm", highway), out)
    assert done.returncode == 1
    assert "no road a car may use" in done.stderr and "Traceback" not in done.stderr
    assert out.read_text() == "the user's own file\n"
    assert not list(tmp_path.glob(".osm_to_net_*"))
