"""Paths and small builders shared by the tests."""

from __future__ import annotations

import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
URBAN_GRID_NET = REPO / "networks" / "urban_grid" / "urban_grid.net.xml"
PAPER_WORLD = REPO / "networks" / "paper_world"


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
