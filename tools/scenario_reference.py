"""Generate docs/scenarios.md, the reference of every scenario key, from the dataclasses.

The schema of a scenario file is the tree of frozen dataclasses under
`platoon_sumo.scenario.Scenario` (the loader in `platoon_sumo.config_loader` walks the
same tree), so the reference is generated from it: key path, type in YAML words,
default, and the attribute docstring (the string literal right after a field in the class
body, read with `ast` because Python does not keep it). Registered controllers (with
their `Params`), vehicle models and laser presets are listed from their registries, and
the repository's default scenario is included verbatim as the worked example.

    python tools/scenario_reference.py           # (re)write docs/scenarios.md
    python tools/scenario_reference.py --check   # exit 1 if the committed file differs
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import difflib
import inspect
import itertools
import math
import sys
import textwrap
import types
import typing
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, Union, get_args, get_origin, get_type_hints

from platoon_sumo.control import CONTROLLERS
from platoon_sumo.scenario import CAR_FOLLOW_MODELS, Scenario
from platoon_sumo.sensors.laser import LASER_PRESETS, LaserConfig
from platoon_sumo.vehicles import VEHICLE_MODELS

ROOT = Path(__file__).resolve().parent.parent
OUTPUT = ROOT / "docs" / "scenarios.md"
EXAMPLE = ROOT / "scenarios" / "urban_grid.yaml"

# What the loader does beyond the dataclass defaults (platoon_sumo.scenario.load_scenario).
_DEFAULT_OVERRIDES = {
    "name": "the file name without `.yaml`",
    "network": "**required**",
}

# Meanings of fields that have no attribute docstring in the code yet, by `Class.field`.
# A docstring in the code always wins; `python tools/scenario_reference.py` lists the
# fields that still rely on this table, and the entries made redundant by a docstring.
_FALLBACK_DOCS = {
    "Scenario.name": "Run name: the default results folder is `results/<name>`.",
    "Scenario.description": "Free text for people; the run does not use it.",
    "SimulationConfig.begin_s": "Simulated time at which SUMO starts [s].",
    "NetworkConfig.route_files": "SUMO route files (`.rou.xml`) loaded with the network.",
    "TrafficConfig.vehicle_types": "Vehicle types of the human-driven traffic; flows and "
    "random trips without a `type` draw from them by `probability`.",
    "TrafficConfig.route_files": "SUMO route files (`.rou.xml`) of human-driven traffic.",
    "TrafficConfig.flows": "Flows of human-driven vehicles between two edges, routed by SUMO.",
    "TrafficConfig.random_trips": "Random trips all over the network (null: none).",
    "VehicleTypeConfig.id": "Type id; `traffic.flows[].type` refers to it.",
    "VehicleTypeConfig.car_follow_model": "SUMO car-following model (list below).",
    "VehicleTypeConfig.vclass": "SUMO vehicle class; decides which lanes the type may use.",
    "VehicleTypeConfig.length_m": "Length, bumper to bumper [m].",
    "VehicleTypeConfig.width_m": "Width [m].",
    "VehicleTypeConfig.min_gap_m": "Gap kept to the vehicle ahead when stopped [m].",
    "VehicleTypeConfig.max_speed_mps": "Top speed [m/s].",
    "VehicleTypeConfig.accel_mps2": "Maximum acceleration [m/s²].",
    "VehicleTypeConfig.decel_mps2": "Comfortable deceleration [m/s²].",
    "VehicleTypeConfig.emergency_decel_mps2": "Deceleration in an emergency [m/s²].",
    "VehicleTypeConfig.speed_factor": "Mean multiplier on lane speed limits (SUMO speedFactor).",
    "VehicleTypeConfig.speed_dev": "Spread of the speed factor between drivers (SUMO speedDev).",
    "VehicleTypeConfig.lane_change_model": "SUMO lane-change model.",
    "FlowConfig.from_edge": "First edge of the flow's route.",
    "FlowConfig.to_edge": "Last edge of the flow's route.",
    "FlowConfig.vehs_per_hour": "Vehicles an hour.",
    "FlowConfig.via_edges": "Edges the route must pass, in order.",
    "FlowConfig.begin_s": "Start of the flow [s].",
    "RandomTripsConfig.begin_s": "Time of the first departure [s].",
    "RandomTripsConfig.end_s": "End of the departures [s]; default: the simulation's end.",
    "RandomTripsConfig.min_distance_m": "Shortest distance between a trip's start and end [m].",
    "PlatoonConfig.id": "Platoon name; its vehicles are `<id>.0` (leader), `<id>.1`, ...",
    "PlatoonConfig.route": "The route every member drives.",
    "PlatoonConfig.members": "Number of vehicles (1 to 100); member 0 leads.",
    "PlatoonConfig.depart_s": "When the platoon is handed to SUMO for insertion [s].",
    "PlatoonConfig.depart_lane": "Lane index on the first edge (0 = rightmost); default 0.",
    "PlatoonConfig.vehicle": "Geometry, motion model and limits of the members.",
    "PlatoonConfig.leader": "Controller of member 0.",
    "PlatoonConfig.follower": "Controller of members 1 and up.",
    "RouteConfig.edges": "The route as the full list of connected edges.",
    "RouteConfig.from_edge": "Start edge; the fastest route to `to_edge` is computed.",
    "RouteConfig.to_edge": "Destination edge (with `from_edge`).",
    "RouteConfig.via_edges": "Edges the computed route must pass, in order.",
    "VehicleConfig.length_m": "Length, bumper to bumper [m].",
    "VehicleConfig.width_m": "Width [m].",
    "VehicleConfig.wheelbase_m": "Rear axle to front axle [m] (bicycle model).",
    "VehicleConfig.max_speed_mps": "Top speed [m/s].",
    "VehicleConfig.max_accel_mps2": "Maximum acceleration [m/s²].",
    "VehicleConfig.max_decel_mps2": "Maximum braking deceleration [m/s²].",
    "VehicleConfig.max_yaw_rate_radps": "Largest yaw rate [rad/s].",
    "VehicleConfig.max_steer_rad": "Front-wheel steering limit [rad] (bicycle model).",
    "VehicleConfig.vclass": "SUMO vehicle class of the platoon's vehicle type.",
    "ControllerConfig.params": "The controller's parameters (see Controllers below).",
    "SensorConfig.preset": "A laser preset (see Laser presets below).",
    "SensorConfig.overrides": "Laser fields replacing the preset's (see Laser presets below).",
}

INTRO = """\
# Scenario files

A scenario is one YAML file: the network, the human-driven traffic, the platoons and
what to record. `platoon-sumo validate FILE` checks a file without running it;
`platoon-sumo run FILE` runs it.

This page is generated by `tools/scenario_reference.py` from the configuration
dataclasses in `platoon_sumo/scenario.py` and the plug-in registries; do not edit it by
hand (`python tools/scenario_reference.py` rewrites it, and the test suite fails when
it is out of date).

Rules that hold for every key:

- **Paths** (`network.net_file`, `network.sumocfg`, `*.route_files`,
  `network.additional_files`) are relative to the scenario file, or absolute.
  `sumo:<path>` points inside the installed `eclipse-sumo` package, e.g.
  `net_file: sumo:tools/game/DRT/osm.net.xml`. Only `outputs.directory` is relative to
  the working directory.
- **Unknown keys are errors**, with a "did you mean" hint for a near miss; so are wrong
  types and values out of range.
- **Errors name the file and the key path** and the command exits with code 2, e.g.
  `error: scenarios/x.yaml: platoons[0].route.edges[2]: unknown edge 'B1B9' (did you
  mean 'B1B0'?)`.
- In key paths below, `[]` stands for any item of a list; errors show its index
  (`platoons[0]`). A key whose default is "section" is a mapping whose keys all have
  defaults; leave it out to take them all.
- `null` means "not set" (YAML `null` or `~`); numbers may be written as integers where
  a number is expected.
"""


# --------------------------------------------------------------------------- docstrings


def attribute_docs(cls: type) -> dict[str, str]:
    """Attribute docstrings of a class (and its dataclass bases), by field name."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if klass is object or not dataclasses.is_dataclass(klass):
            continue
        tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        body = tree.body[0].body if isinstance(tree.body[0], ast.ClassDef) else []
        for stmt, nxt in itertools.pairwise(body):
            if (
                isinstance(stmt, ast.AnnAssign)
                and isinstance(stmt.target, ast.Name)
                and isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)
            ):
                docs[stmt.target.id] = _one_line(nxt.value.value)
    return docs


def class_doc(obj: Any) -> str:
    """First paragraph of an object's docstring, on one line."""
    doc = inspect.getdoc(obj) or ""
    return _one_line(doc.split("\n\n")[0])


def _one_line(text: str) -> str:
    return " ".join(inspect.cleandoc(text).split())


# --------------------------------------------------------------------------- types and values


_WORDS = {float: "number", int: "integer", str: "string", bool: "boolean"}


def yaml_type(tp: Any) -> str:
    """A type annotation in the words of a YAML author."""
    if tp is Any:
        return "any"
    if tp in _WORDS:
        return _WORDS[tp]
    if dataclasses.is_dataclass(tp):
        return "mapping"
    origin = get_origin(tp)
    args = get_args(tp)
    if origin is typing.Literal:
        return "one of " + ", ".join(f"`{a}`" for a in args)
    if origin in (Union, types.UnionType):
        options = [a for a in args if a is not type(None)]
        if float in options and int in options:  # YAML integers are accepted as numbers
            options.remove(int)
        words = " or ".join(yaml_type(a) for a in options)
        return f"{words} or null" if type(None) in args else words
    if origin in (tuple, list):
        return f"list of {_plural(yaml_type(args[0]) if args else 'any')}"
    if origin in (dict, Mapping):
        if not args or args[1] is Any:
            return "mapping"
        return f"mapping of {yaml_type(args[0])} to {yaml_type(args[1])}"
    raise TypeError(f"no YAML word for {tp!r}")


def _plural(word: str) -> str:
    return word if word in ("any",) else f"{word}s"


def yaml_value(value: Any) -> str:
    """A default value as it would be written in YAML."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    if isinstance(value, int | str):
        return '""' if value == "" else str(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(yaml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}: {yaml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"no YAML rendering for {value!r}")


def _default(field: dataclasses.Field[Any], tp: Any) -> str:
    if field.default is not dataclasses.MISSING:
        value = field.default
    elif field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    else:
        return "**required**"
    if dataclasses.is_dataclass(value):
        return "section"
    return f"`{yaml_value(value)}`"


def _item_dataclass(tp: Any) -> type | None:
    """The dataclass a field holds (directly, optionally, or as list items), if any."""
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return tp
    origin = get_origin(tp)
    if origin in (Union, types.UnionType, tuple, list):
        for arg in get_args(tp):
            found = _item_dataclass(arg)
            if found is not None:
                return found
    return None


# --------------------------------------------------------------------------- tables


@dataclasses.dataclass(frozen=True)
class Section:
    path: str
    cls: type
    rows: tuple[tuple[str, str, str, str], ...]


def sections(cls: type, path: str = "") -> Iterator[Section]:
    """One section per dataclass in the tree, parents before children, in field order."""
    hints = get_type_hints(cls)
    docs = attribute_docs(cls)
    rows = []
    children: list[tuple[str, type]] = []
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        tp = hints[f.name]
        key = f"{path}.{f.name}" if path else f.name
        default = _DEFAULT_OVERRIDES.get(key) or _default(f, tp)
        child = _item_dataclass(tp)
        doc = docs.get(f.name) or _FALLBACK_DOCS.get(f"{cls.__name__}.{f.name}", "")
        if child is not None:
            is_list = get_origin(tp) in (tuple, list)
            child_path = f"{key}[]" if is_list else key
            children.append((child_path, child))
            see = f"keys under `{child_path}` below"
            doc = f"{doc} See {see}." if doc else f"See {see}."
        rows.append((f"`{key}`", yaml_type(tp), default, doc))
    yield Section(path, cls, tuple(rows))
    for child_path, child in children:
        yield from sections(child, child_path)


def table(rows: Any) -> list[str]:
    lines = ["| key | type | default | meaning |", "|---|---|---|---|"]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return lines


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def params_rows(params_cls: type, prefix: str) -> list[tuple[str, str, str, str]]:
    return [row for s in sections(params_cls, prefix) for row in s.rows]


# --------------------------------------------------------------------------- the page


def render() -> str:
    out = [INTRO]
    out += ["## Keys", ""]
    for s in sections(Scenario):
        title = f"`{s.path}`" if s.path else "Top level"
        out += [f"### {title}", ""]
        doc = class_doc(s.cls) if s.cls.__doc__ and not _is_generated_doc(s.cls) else ""
        if doc:
            out += [doc, ""]
        out += [*table(s.rows), ""]

    out += [
        "## Car-following models",
        "",
        "`traffic.vehicle_types[].car_follow_model` is one of SUMO's models: "
        + ", ".join(f"`{m}`" for m in CAR_FOLLOW_MODELS)
        + ". Their own parameters (e.g. `delta` for `IDM`) go in "
        "`traffic.vehicle_types[].params`.",
        "",
    ]

    out += [
        "## Controllers",
        "",
        "`platoons[].leader.type` and `platoons[].follower.type` name a registered "
        "controller, or a class of your own as `package.module:Class` (a class with a "
        "`Params` dataclass, `reset()` and `step()`, see `platoon_sumo/control/base.py`). "
        "The controller's parameters go under `leader.params` / `follower.params` and are "
        "checked like every other key.",
        "",
    ]
    for name in CONTROLLERS.names():
        ctrl = CONTROLLERS.get(name)
        out += [f"### `{name}`", "", class_doc(ctrl), ""]
        out += [*table(params_rows(ctrl.Params, "params")), ""]

    out += [
        "## Vehicle models",
        "",
        "`platoons[].vehicle.model` is one of:",
        "",
        "| model | description |",
        "|---|---|",
    ]
    out += [f"| `{n}` | {_cell(class_doc(VEHICLE_MODELS.get(n)))} |" for n in VEHICLE_MODELS]
    out += [""]

    out += laser_section()

    out += [
        "## Example",
        "",
        f"The default scenario, `{EXAMPLE.relative_to(ROOT).as_posix()}`:",
        "",
        "```yaml",
        EXAMPLE.read_text(encoding="utf-8").rstrip("\n"),
        "```",
        "",
    ]
    return "\n".join(out)


def _is_generated_doc(cls: type) -> bool:
    """dataclasses writes `Name(field: type, ...)` as the docstring of an undocumented class."""
    return (cls.__doc__ or "").startswith(f"{cls.__name__}(")


def laser_section() -> list[str]:
    names = [f.name for f in dataclasses.fields(LaserConfig)]
    out = [
        "## Laser presets",
        "",
        "`platoons[].sensor.preset` is one of the presets below; "
        "`platoons[].sensor.overrides` replaces any of these fields, e.g. "
        "`{noise_std_m: 0.01, range_max_m: 10}`. Angles are in radians in the sensor "
        "frame (counter-clockwise from the sensor's forward axis); the mount pose is "
        "relative to the vehicle's front bumper centre, x forward, y left.",
        "",
        "| preset | " + " | ".join(f"`{n}`" for n in names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for preset in sorted(LASER_PRESETS):
        cfg = LASER_PRESETS[preset]
        cells = [_preset_value(n, getattr(cfg, n)) for n in names]
        out.append(f"| `{preset}` | " + " | ".join(cells) + " |")
    out.append("")
    return out


def _preset_value(name: str, value: Any) -> str:
    if name.endswith("_rad") and value:
        return f"{value:.6g} ({math.degrees(value):.6g}°)"
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def fallback_report() -> tuple[list[str], list[str]]:
    """Fields documented only by `_FALLBACK_DOCS`, and entries a docstring made redundant."""
    used: list[str] = []
    redundant: list[str] = []
    known: set[str] = set()
    for s in sections(Scenario):
        docs = attribute_docs(s.cls)
        for f in dataclasses.fields(s.cls):
            key = f"{s.cls.__name__}.{f.name}"
            known.add(key)
            if key in _FALLBACK_DOCS:
                (redundant if docs.get(f.name) else used).append(key)
    redundant += [k for k in _FALLBACK_DOCS if k not in known]
    return sorted(set(used)), sorted(set(redundant))


# --------------------------------------------------------------------------- command line


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--check", action="store_true", help="exit 1 if the committed file is out of date"
    )
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        current = OUTPUT.read_text(encoding="utf-8") if OUTPUT.is_file() else ""
        if current == text:
            return 0
        diff = difflib.unified_diff(
            current.splitlines(), text.splitlines(), "committed", "generated", lineterm="", n=1
        )
        shown = list(diff)[:40]
        print("\n".join(shown), file=sys.stderr)
        print(
            f"{OUTPUT.relative_to(ROOT)} is out of date: run python tools/scenario_reference.py",
            file=sys.stderr,
        )
        return 1
    OUTPUT.parent.mkdir(parents=True, exist_ok=True)
    OUTPUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUTPUT.relative_to(ROOT)}")
    used, redundant = fallback_report()
    if used:
        print(
            f"{len(used)} fields have no docstring (meaning taken from _FALLBACK_DOCS):",
            file=sys.stderr,
        )
        print("  " + ", ".join(used), file=sys.stderr)
    if redundant:
        print(
            "delete from _FALLBACK_DOCS (documented in the code, or gone): " + ", ".join(redundant),
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
