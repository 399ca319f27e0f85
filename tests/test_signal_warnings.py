"""`validate` and `run` warn about signal phases that would lock the traffic (game and
test programs with 1,000 s greens), naming the file, the light and the phase."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from platoon_sumo.cli import main
from tests.helpers import URBAN_GRID_NET


def scenario(tmp_path: Path, net: Path, additional: list[str] | None = None) -> Path:
    data = {
        "simulation": {"end_s": 5},
        "network": {"net_file": str(net), "additional_files": additional or []},
        "platoons": [{"id": "ego", "route": {"edges": ["left1A1", "A1B1"]}}],
    }
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_a_shipped_network_validates_without_warnings(tmp_path, capfd):
    assert main(["validate", str(scenario(tmp_path, URBAN_GRID_NET))]) == 0
    out, err = capfd.readouterr()
    assert "OK" in out and err == ""


def test_a_long_phase_in_the_network_is_named(tmp_path, capfd):
    net = tmp_path / "locked.net.xml"
    text = URBAN_GRID_NET.read_text(encoding="utf-8")
    net.write_text(text.replace('duration="42"', 'duration="2000"', 1), encoding="utf-8")
    assert main(["validate", str(scenario(tmp_path, net))]) == 0
    out, err = capfd.readouterr()
    assert "OK" in out
    (line,) = err.splitlines()
    assert line.startswith(f"warning: {net}: traffic light 'A0' (program '0') phase 0")
    assert "lasts 2000 s, longer than 300 s" in line


PROGRAMS = {
    "static": '<tlLogic id="B1" type="static" programID="game" offset="0">'
    '<phase duration="30" state="GGGgrrrrGGGgrrrr"/>'
    '<phase duration="9999" state="rrrrGGGgrrrrGGGg"/></tlLogic>',
    "actuated": '<tlLogic id="B1" type="actuated" programID="game" offset="0">'
    '<phase duration="30" minDur="5" maxDur="60" state="GGGgrrrrGGGgrrrr"/>'
    '<phase duration="30" minDur="5" maxDur="9999" state="rrrrGGGgrrrrGGGg"/></tlLogic>',
}


@pytest.mark.parametrize("kind", sorted(PROGRAMS))
def test_a_long_phase_in_an_additional_program_is_named(tmp_path, capfd, kind):
    extra = tmp_path / "game.add.xml"
    extra.write_text(f"<additional>{PROGRAMS[kind]}</additional>", encoding="utf-8")
    path = scenario(tmp_path, URBAN_GRID_NET, [str(extra)])
    assert main(["validate", str(path)]) == 0
    (line,) = capfd.readouterr().err.splitlines()
    assert f"{extra}: traffic light 'B1' (program 'game') phase 1" in line
    assert "lasts 9999 s" in line


def test_an_additional_file_that_is_not_xml_is_one_error_line(tmp_path, capfd):
    broken = tmp_path / "broken.add.xml"
    broken.write_text("<additional><tlLogic id='x'>", encoding="utf-8")
    path = scenario(tmp_path, URBAN_GRID_NET, [str(broken)])
    code = main(["validate", str(path)])
    err = capfd.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert str(path) in err and str(broken) in err and "cannot be read as XML" in err


def test_a_long_program_replaced_by_an_additional_one_is_not_reported(tmp_path, capfd):
    net = tmp_path / "locked.net.xml"
    text = URBAN_GRID_NET.read_text(encoding="utf-8")
    net.write_text(text.replace('duration="42"', 'duration="2000"', 1), encoding="utf-8")
    fixed = tmp_path / "fixed.add.xml"  # SUMO runs the last program loaded for a light
    fixed.write_text(
        '<additional><tlLogic id="A0" type="static" programID="fixed" offset="0">'
        '<phase duration="40" state="GGGgrrrrGGGgrrrr"/>'
        '<phase duration="40" state="rrrrGGGgrrrrGGGg"/></tlLogic></additional>',
        encoding="utf-8",
    )
    assert main(["validate", str(scenario(tmp_path, net, [str(fixed)]))]) == 0
    assert capfd.readouterr().err == ""
