"""A study's runs: the parameter combinations times the repetitions, each a scenario
with the values set at their key paths and its own seed, written and checked before the
first run starts."""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from platoon_sumo.errors import PlatoonSumoError, ScenarioError
from platoon_sumo.study.spec import Study, parse_key_path

#: Scenario keys holding file paths, made absolute so a run's scenario works from the
#: study folder.
PATH_KEYS = (("network", "net_file"), ("network", "sumocfg"), ("network", "route_files"),
             ("network", "additional_files"), ("traffic", "route_files"))  # fmt: skip


@dataclass(frozen=True)
class StudyRun:
    """One run: the parameter values, the repetition and its seed."""

    values: Mapping[str, Any]
    repetition: int
    seed: int

    @property
    def run_id(self) -> str:
        """A name from the values and the seed: the same run gets the same folder."""
        text = json.dumps([dict(self.values), self.repetition, self.seed], sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    def describe(self) -> str:
        values = ", ".join(f"{k}={v!r}" for k, v in self.values.items())
        return f"run {self.run_id} ({values or 'base scenario'}, seed {self.seed})"


def repetition_seed(study_seed: int, repetition: int) -> int:
    """The scenario seed of repetition `repetition`: independent streams from one study
    seed, the same for every combination and any number of workers."""
    state = np.random.SeedSequence([study_seed, repetition]).generate_state(1)[0]
    return int(state) % (2**31 - 1)


def expand(study: Study) -> list[StudyRun]:
    """Every run of the study, in a fixed order (combination, then repetition)."""
    keys = list(study.values)
    lists = [study.values[k] for k in keys]
    if study.config.combine == "grid":
        combos = list(itertools.product(*lists))
    else:
        combos = list(zip(*lists, strict=True)) if lists else [()]
    return [
        StudyRun(dict(zip(keys, combo, strict=True)), r, repetition_seed(study.config.seed, r))
        for combo in combos
        for r in range(study.config.repetitions)
    ]


def scenario_for(study: Study, run: StudyRun) -> dict[str, Any]:
    """The base scenario with the run's values, seed and end time, paths absolute."""
    data = copy.deepcopy(dict(study.scenario_data))
    settings: list[tuple[str, Any]] = []
    for key, value in run.values.items():
        group = study.groups.get(key)
        settings.extend(group[value].items() if group is not None else [(key, value)])
    for key, value in settings:
        _set(data, parse_key_path(key, str(study.path)), value, key, str(study.path))
    simulation = dict(data.get("simulation") or {})
    simulation["seed"] = run.seed
    if study.config.end_s is not None:
        simulation["end_s"] = study.config.end_s
    data["simulation"] = simulation
    base = study.scenario_path.parent
    for section, key in PATH_KEYS:
        part = data.get(section)
        if not isinstance(part, dict) or key not in part:
            continue
        value = part[key]
        if isinstance(value, str):
            part[key] = _absolute(value, base)
        elif isinstance(value, list):
            part[key] = [_absolute(v, base) if isinstance(v, str) else v for v in value]
    data["name"] = f"{study.name}_{run.run_id}"
    data.setdefault("outputs", {})
    if isinstance(data["outputs"], dict):
        data["outputs"].pop("directory", None)  # each run writes into the study folder
    return data


def write_scenarios(study: Study, runs: list[StudyRun], folder: Path) -> dict[str, Path]:
    """Write each run's scenario into `folder` and check it as `validate` does (network
    included) before any run starts; raise one error naming the run and its values."""
    from platoon_sumo.scenario import load_scenario, prepare

    folder.mkdir(parents=True, exist_ok=True)
    paths = {}
    for run in runs:
        path = folder / f"{run.run_id}.yaml"
        text = yaml.safe_dump(scenario_for(study, run), sort_keys=False)
        header = f"# {run.describe()} of study {study.path}\n"
        path.write_text(header + text, encoding="utf-8")
        try:
            prepare(load_scenario(path))
        except ScenarioError as exc:
            raise ScenarioError(
                str(study.path), "parameters", f"{run.describe()}: {exc.key_path or '<top>'}: "
                f"{exc.message}", exc.hint,
            ) from None  # fmt: skip
        except PlatoonSumoError as exc:
            raise ScenarioError(str(study.path), "parameters", f"{run.describe()}: {exc}") from None
        paths[run.run_id] = path
    return paths


def _absolute(value: str, base: Path) -> str:
    if value.startswith("sumo:"):
        return value
    p = Path(value)
    return str(p if p.is_absolute() else (base / p).resolve())


def _set(data: Any, path: list[str | int | None], value: Any, key: str, file: str) -> None:
    """Set `value` at `path` (None: every element of a list), creating mappings on the
    way; an index beyond a list, or a step into a value, is an error naming the key."""
    *head, last = path
    nodes = [data]
    for step in head:
        nxt = []
        for node in nodes:
            nxt.extend(_children(node, step, key, file))
        nodes = nxt
    for node in nodes:
        if last is None:
            if not isinstance(node, list):
                raise ScenarioError(file, f"parameters.{key}", "[*] on a value that is not a list")
            node[:] = [copy.deepcopy(value) for _ in node]
        elif isinstance(last, int):
            if not isinstance(node, list) or last >= len(node):
                raise ScenarioError(file, f"parameters.{key}",
                                    f"index {last} beyond the scenario's list")  # fmt: skip
            node[last] = copy.deepcopy(value)
        else:
            if not isinstance(node, dict):
                raise ScenarioError(file, f"parameters.{key}", f"'{last}' inside a value")
            node[last] = copy.deepcopy(value)


def _children(node: Any, step: str | int | None, key: str, file: str) -> list[Any]:
    where = f"parameters.{key}"
    if step is None:
        if not isinstance(node, list):
            raise ScenarioError(file, where, "[*] on a value that is not a list")
        return list(node)
    if isinstance(step, int):
        if not isinstance(node, list) or step >= len(node):
            raise ScenarioError(file, where, f"index {step} beyond the scenario's list")
        return [node[step]]
    if not isinstance(node, dict):
        raise ScenarioError(file, where, f"'{step}' inside a value")
    if node.get(step) is None:
        node[step] = {}
    return [node[step]]
