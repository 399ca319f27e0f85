"""A study file: a base scenario, the parameters to vary, repetitions and the metrics to
collect, loaded and checked as strictly as scenarios (file, key, did-you-mean)."""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from platoon_sumo.config_loader import bounded, load_dataclass, require, require_choice
from platoon_sumo.errors import ScenarioError, did_you_mean
from platoon_sumo.yaml_input import read_mapping

#: Tables a metric can be read from: summary.json (dotted keys), and the per-platoon and
#: per-vehicle tables (a column, reduced over their rows).
SOURCES = ("summary", "platoons", "vehicles")
REDUCERS = ("mean", "min", "max", "sum", "count")
#: Largest number of runs one study may expand to (a typo in a range should not start
#: a million simulations).
MAX_RUNS = 100_000


@dataclass(frozen=True)
class StudyConfig:
    """What a study runs: every combination of `parameters` (grid product, or the lists
    zipped), each `repetitions` times with seeds derived from `seed`."""

    scenario: str
    """The base scenario file, relative to the study file."""
    metrics: tuple[str, ...]
    """What to collect from each run: `summary.<dotted key>` of summary.json, or
    `platoons.<column>` / `vehicles.<column>` of platoons.csv / vehicles.csv reduced
    over their rows with `:mean` (default), `:min`, `:max`, `:sum` or `:count`."""
    parameters: Mapping[str, Any] = field(default_factory=dict)
    """Key path into the scenario (`platoons[0].follower.params.time_gap_s`,
    `platoons[*].leader.params.cruise_speed_mps`, `traffic.scale`) -> a list of values,
    or `{from: a, to: b, step: c}` (both ends included); or a name -> named levels,
    each a mapping of key paths to values set together (`follower: {paper: {...},
    laser: {...}}`), the level's name in the table."""
    combine: Literal["grid", "zip"] = "grid"
    """`grid`: every combination; `zip`: the i-th values of every list together."""
    repetitions: int = bounded(1, ge=1, le=10_000)
    """Runs per combination, each with its own seed."""
    seed: int = bounded(0, ge=0, le=2**31 - 1)
    """Study seed: repetition r of every combination runs with the same scenario seed,
    derived from this one (common random numbers across combinations)."""
    end_s: float | None = bounded(None, gt=0, le=1e7)
    """Override of the scenario's `simulation.end_s` [s]."""
    description: str = ""

    def __post_init__(self) -> None:
        require_choice(self.combine, ("grid", "zip"), "combine")
        require(len(self.metrics) > 0, "metrics", "name at least one metric to collect")
        for i, metric in enumerate(self.metrics):
            parse_metric(metric, f"metrics[{i}]")


@dataclass(frozen=True)
class Metric:
    source: str
    key: str
    reducer: str = "mean"


def parse_metric(text: str, key: str) -> Metric:
    """`summary.overall.min_gap_m` or `platoons.max_accel_l2_gain:max` -> Metric."""
    source, dot, rest = text.partition(".")
    require(bool(dot and rest), key, f"'{text}' is not <source>.<key>",
            f"source one of {', '.join(SOURCES)}")  # fmt: skip
    require(source in SOURCES, key, f"unknown source '{source}'",
            did_you_mean(source, SOURCES) or f"one of {', '.join(SOURCES)}")  # fmt: skip
    name, colon, reducer = rest.partition(":")
    if source == "summary":
        require(not colon, key, "summary keys take no reducer (a single value per run)")
        return Metric(source, name)
    reducer = reducer or "mean"
    require(reducer in REDUCERS, key, f"unknown reducer '{reducer}'",
            did_you_mean(reducer, REDUCERS) or f"one of {', '.join(REDUCERS)}")  # fmt: skip
    return Metric(source, name, reducer)


@dataclass(frozen=True)
class Study:
    """A loaded study: its config, file, and the base scenario as parsed YAML."""

    config: StudyConfig
    path: Path
    text: str
    scenario_path: Path
    scenario_data: Mapping[str, Any]
    values: Mapping[str, tuple[Any, ...]]
    """Each parameter's values, in file order (a group's: its level names)."""
    groups: Mapping[str, Mapping[str, Mapping[str, Any]]] = field(default_factory=dict)
    """Named groups: {name: {level: {key path: value}}}, several keys set together."""

    @property
    def name(self) -> str:
        return re.sub(r"[^A-Za-z0-9_.-]", "_", self.path.stem) or "study"

    @property
    def sha256(self) -> str:
        """Of the study file and the base scenario's text: a study folder holds one."""
        digest = hashlib.sha256(self.text.encode())
        digest.update(self.scenario_path.read_bytes())
        return digest.hexdigest()


def load_study(path: str | Path) -> Study:
    """Read and check a study file and its base scenario's YAML (not yet each run)."""
    p = Path(path)
    shown = str(path)
    text, data = read_mapping(p, shown, "study")
    config = load_dataclass(StudyConfig, data, shown)
    scenario_path = (p.parent / config.scenario).resolve()
    if not scenario_path.is_file():
        raise ScenarioError(shown, "scenario", f"scenario file not found: {scenario_path}")
    _, scenario_data = read_mapping(scenario_path, str(scenario_path))
    groups = {
        k: _group(v, shown, f"parameters.{k}")
        for k, v in config.parameters.items()
        if isinstance(v, Mapping) and set(v) != {"from", "to", "step"}
    }
    values = {
        k: tuple(groups[k]) if k in groups else _values(v, shown, f"parameters.{k}")
        for k, v in config.parameters.items()
    }
    for key in values:
        if key not in groups:
            parse_key_path(key, shown)
    if config.combine == "zip" and len({len(v) for v in values.values()}) > 1:
        lengths = ", ".join(f"{k}: {len(v)}" for k, v in values.items())
        raise ScenarioError(shown, "parameters", f"zip needs lists of one length ({lengths})",
                            "use combine: grid for every combination")  # fmt: skip
    runs = config.repetitions * (
        math.prod(len(v) for v in values.values())
        if config.combine == "grid"
        else max((len(v) for v in values.values()), default=1)
    )
    if runs > MAX_RUNS:
        raise ScenarioError(shown, "parameters", f"{runs} runs; a study is limited to {MAX_RUNS}")
    return Study(config, p.resolve(), text, scenario_path, scenario_data, values, groups)


def _values(spec: Any, file: str, key: str) -> tuple[Any, ...]:
    """A parameter's values: a non-empty list, or {from, to, step} with both ends in."""
    if isinstance(spec, list | tuple):
        if not spec:
            raise ScenarioError(file, key, "needs at least one value")
        return tuple(spec)
    if isinstance(spec, Mapping):
        unknown = set(spec) - {"from", "to", "step"}
        if unknown or not {"from", "to", "step"} <= set(spec):
            raise ScenarioError(file, key, "a range is {from: a, to: b, step: c}")
        start, stop, step = (spec[k] for k in ("from", "to", "step"))
        if not all(isinstance(x, int | float) and math.isfinite(x) for x in (start, stop, step)):
            raise ScenarioError(file, key, "from, to and step must be finite numbers")
        if step <= 0 or stop < start:
            raise ScenarioError(file, key, "needs step > 0 and to >= from")
        count = math.floor((stop - start) / step + 1e-9) + 1
        if count > MAX_RUNS:
            raise ScenarioError(file, key, f"{count} values; at most {MAX_RUNS}")
        integral = all(isinstance(x, int) for x in (start, stop, step))
        return tuple(
            start + i * step if integral else round(start + i * step, 12) for i in range(count)
        )
    raise ScenarioError(file, key, "expected a list of values or {from, to, step}")


def _group(spec: Mapping[str, Any], file: str, key: str) -> dict[str, dict[str, Any]]:
    """A named group: {level: {key path: value}} (a range is {from, to, step})."""
    if not spec:
        raise ScenarioError(file, key, "a group needs at least one level")
    levels = {}
    for level, settings in spec.items():
        where = f"{key}.{level}"
        if not isinstance(settings, Mapping) or not settings:
            raise ScenarioError(file, where, "a level is a mapping of key paths to values",
                                "or write a range as {from: a, to: b, step: c}")  # fmt: skip
        for path in settings:
            parse_key_path(str(path), file)
        levels[str(level)] = dict(settings)
    return levels


_PART = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[(?:\d+|\*)\])*)$")


def parse_key_path(key: str, file: str) -> list[str | int | None]:
    """`platoons[0].follower.params.time_gap_s` -> ['platoons', 0, 'follower', ...];
    `[*]` is None (every element)."""
    out: list[str | int | None] = []
    for part in key.split("."):
        m = _PART.match(part)
        if m is None:
            hint = "write keys like platoons[0].follower.params.time_gap_s"
            raise ScenarioError(file, f"parameters.{key}", f"'{part}' is not a key step", hint)
        out.append(m.group(1))
        for index in re.findall(r"\[(\d+|\*)\]", m.group(2)):
            out.append(None if index == "*" else int(index))
    return out
