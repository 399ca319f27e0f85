"""Paths shared by the tests."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
URBAN_GRID_NET = REPO / "networks" / "urban_grid" / "urban_grid.net.xml"
PAPER_WORLD = REPO / "networks" / "paper_world"
