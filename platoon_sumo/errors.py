"""Exceptions users see. The CLI turns each into one line and exit code 2."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class PlatoonSumoError(Exception):
    """Base of every error this package raises on purpose."""


class ScenarioError(PlatoonSumoError):
    """A scenario file is wrong: names the file, the key path and what was expected."""

    def __init__(self, file: str, key_path: str, message: str, hint: str | None = None):
        self.file = file
        self.key_path = key_path
        self.message = message
        self.hint = hint
        text = f"{file}: {key_path or '<top level>'}: {message}"
        if hint:
            text += f" ({hint})"
        super().__init__(text)


class Terminated(KeyboardInterrupt):
    """SIGTERM (a cluster ending the job, `kill`), raised where the program is, so a run
    ends as on Ctrl-C: what it wrote is kept and marked interrupted."""


class UsageError(PlatoonSumoError):
    """A command's input that cannot be used as given: a results folder without the file
    the command needs, an argument naming nothing in it. Names the folder or argument."""


class SumoError(PlatoonSumoError):
    """SUMO refused something (start, insertion, a move); carries SUMO's own words."""


def did_you_mean(word: str, choices: Iterable[str]) -> str | None:
    """A 'did you mean' hint for a misspelt name, or None when nothing is close."""
    matches = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f"did you mean '{matches[0]}'?" if matches else None


class PluginError(PlatoonSumoError):
    """A plug-in (controller, sensor, actuator) failed during a run: names the plug-in,
    the vehicle and the simulated time."""
