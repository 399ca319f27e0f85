"""Checks of a network's traffic-light programs before a run (read from the files, no
SUMO needed)."""

from __future__ import annotations

import gzip
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path
from typing import IO

#: A signal phase longer than this [s] is reported: a red that long locks the traffic
#: behind it (game and test programs have 1,000-10,000 s phases).
LONG_PHASE_S = 300.0


def long_signal_phases(paths: Iterable[Path], limit_s: float = LONG_PHASE_S) -> list[str]:
    """One message per signal phase lasting longer than `limit_s` (its duration, or its
    maxDur for actuated programs) in the program each light runs: of the `tlLogic`s in
    these network and additional files, in load order, SUMO runs the last one loaded for
    a light (an additional file's program replaces the network's). Messages name the
    file, the light, its program and the phase. A file that is not XML is a ValueError
    naming it."""
    active: dict[str, list[str]] = {}
    for path in paths:
        try:
            active.update(_programs(path, limit_s))
        except (ET.ParseError, OSError, EOFError) as exc:
            raise ValueError(f"{path} cannot be read as XML ({exc})") from None
    return [message for messages in active.values() for message in messages]


def _programs(path: Path, limit_s: float) -> dict[str, list[str]]:
    """{light id: messages about the long phases of its last program in this file}."""
    found: dict[str, list[str]] = {}
    with _open(path) as stream:
        for _, element in ET.iterparse(stream):
            if element.tag != "tlLogic":
                if element.tag in ("edge", "junction", "connection"):
                    element.clear()  # stream through big networks
                continue
            actuated = element.get("type") in ("actuated", "delay_based")
            messages = []
            for index, phase in enumerate(element.iter("phase")):
                seconds = _seconds(phase.get("duration"))
                if actuated:
                    seconds = max(seconds, _seconds(phase.get("maxDur")))
                if seconds > limit_s:
                    messages.append(
                        f"{path}: traffic light '{element.get('id')}' (program "
                        f"'{element.get('programID')}') phase {index} "
                        f"'{phase.get('state')}' lasts {seconds:.0f} s, longer than "
                        f"{limit_s:.0f} s: vehicles may wait that long at its red"
                    )
            found[str(element.get("id"))] = messages
            element.clear()
    return found


def _seconds(value: str | None) -> float:
    try:
        return float(value) if value is not None else 0.0
    except ValueError:
        return 0.0


def _open(path: Path) -> IO[bytes]:
    if path.suffix == ".gz":
        return gzip.open(path, "rb")  # type: ignore[return-value]
    return path.open("rb")
