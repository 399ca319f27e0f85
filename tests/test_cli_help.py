"""Every argument of `validate` and `scan` says what it is (issue 15: their help texts
did not describe their arguments)."""

from __future__ import annotations

import argparse

import pytest

from platoon_sumo.cli import build_parser


def subparser(name: str) -> argparse.ArgumentParser:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


@pytest.mark.parametrize("command", ["validate", "scan"])
def test_every_argument_has_a_help_text(command):
    actions = subparser(command)._actions
    assert len(actions) > 1  # -h and the command's own arguments
    undescribed = [a.dest for a in actions if not (a.help or "").strip()]
    assert undescribed == []


def test_scan_time_names_its_unit():
    at = next(a for a in subparser("scan")._actions if a.dest == "at")
    assert "[s]" in at.help
