"""Bad scenario files: one line on stderr naming file, key path and expectation; exit 2.

Each case starts from a small valid scenario on `networks/urban_grid`, breaks one thing,
and runs `platoon-sumo validate` (and, for some, `platoon-sumo run`) through `cli.main`.
A run must fail before SUMO starts and must not leave a results folder that looks
complete (no summary.json).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

from platoon_sumo.cli import main

ROOT = Path(__file__).resolve().parents[1]
NET = ROOT / "networks" / "urban_grid" / "urban_grid.net.xml"
PLUGINS = Path(__file__).resolve().parent / "plugins"
ROUTE = ["left1A1", "A1B1", "B1B0", "B0A0", "A0left0"]
FILE_NAME = "bad_scenario.yaml"


def valid_scenario() -> dict[str, Any]:
    return {
        "simulation": {"step_s": 0.1, "end_s": 30, "seed": 1},
        "network": {"net_file": str(NET)},
        "traffic": {"vehicle_types": [{"id": "car", "car_follow_model": "IDM"}]},
        "platoons": [
            {
                "id": "ego",
                "route": {"edges": list(ROUTE)},
                "members": 1,
                "vehicle": {"model": "bicycle", "length_m": 4.5},
                "leader": {"type": "route_following"},
            }
        ],
    }


Edit = Callable[[dict[str, Any]], None]


def _walk(data: Any, dotted: str) -> tuple[Any, str | int]:
    """The container holding the last part of `dotted` (numbers index lists)."""
    parts: list[str | int] = [int(p) if p.isdigit() else p for p in dotted.split(".")]
    for part in parts[:-1]:
        data = data[part]
    return data, parts[-1]


def put(dotted: str, value: Any) -> Edit:
    def edit(data: dict[str, Any]) -> None:
        container, last = _walk(data, dotted)
        container[last] = value

    return edit


def drop(dotted: str) -> Edit:
    def edit(data: dict[str, Any]) -> None:
        container, last = _walk(data, dotted)
        del container[last]

    return edit


def edits(*steps: Edit) -> Edit:
    def edit(data: dict[str, Any]) -> None:
        for step in steps:
            step(data)

    return edit


def _sumo_followers(params: dict[str, Any], actuation: str | None = "lane") -> Edit:
    """Two members, the follower a `sumo_driver` with `params` (and `actuation`, if any)."""
    steps = [
        put("platoons.0.members", 2),
        put("platoons.0.follower", {"type": "sumo_driver", "params": params}),
    ]
    if actuation is not None:
        steps.append(put("platoons.0.actuation", actuation))
    return edits(*steps)


@dataclass(frozen=True)
class Case:
    id: str
    key: str
    """Key path the message must name (between the file and the message)."""
    expected: tuple[str, ...]
    """Fragments of the message saying what was wrong / expected."""
    edit: Edit | None = None
    hint: str | None = None
    """A suggestion the message must carry, e.g. "did you mean 'step_s'?"."""
    text: str | bytes | None = None
    """Raw file content instead of the edited valid scenario."""
    missing_file: bool = False
    files: tuple[tuple[str, str], ...] = ()
    """Further files (name, content) written beside the scenario, e.g. route files."""


CASES = [
    # ------------------------------------------------------------------ shape of the file
    Case(
        "unknown_top_level_key",
        "simulatoin",
        ("unknown key", "allowed:", "simulation"),
        put("simulatoin", {"step_s": 0.1}),
        hint="did you mean 'simulation'?",
    ),
    Case(
        "unknown_nested_key",
        "simulation.stepp_s",
        ("unknown key", "allowed:", "step_s"),
        put("simulation.stepp_s", 0.1),
        hint="did you mean 'step_s'?",
    ),
    Case(
        "wrong_type_string_for_number",
        "simulation.end_s",
        ("expected a number", "'soon'"),
        put("simulation.end_s", "soon"),
    ),
    Case(
        "bool_is_not_an_integer",
        "simulation.seed",
        ("expected an integer", "True"),
        put("simulation.seed", True),
    ),
    Case(
        "teleport_time_not_positive",
        "simulation.time_to_teleport_s",
        ("must be a finite number > 0 s",),
        put("simulation.time_to_teleport_s", -1),
    ),
    Case(
        "negative_step",
        "simulation.step_s",
        ("must be > 0",),
        put("simulation.step_s", -0.1),
    ),
    Case("zero_step", "simulation.step_s", ("must be > 0",), put("simulation.step_s", 0)),
    Case("step_too_long", "simulation.step_s", ("must be <= 1",), put("simulation.step_s", 5)),
    Case(
        "end_before_begin",
        "simulation.end_s",
        ("must be after begin_s",),
        edits(put("simulation.begin_s", 50), put("simulation.end_s", 10)),
    ),
    Case(
        "section_is_not_a_mapping",
        "simulation",
        ("expected a mapping", "a list"),
        put("simulation", [0.1, 30]),
    ),
    Case(
        "route_edges_not_a_list",
        "platoons[0].route.edges",
        ("expected a list", "'left1A1'"),
        put("platoons.0.route.edges", "left1A1"),
    ),
    Case(
        "missing_required_key",
        "platoons[0].route",
        ("required key is missing",),
        drop("platoons.0.route"),
    ),
    Case(
        "missing_network_section",
        "network",
        ("required key is missing",),
        drop("network"),
    ),
    Case(
        "missing_scenario_file",
        "<top level>",
        ("scenario file not found",),
        missing_file=True,
    ),
    Case(
        "invalid_yaml_syntax",
        "line 4",  # where the parser notices the unclosed list of line 3
        ("not valid YAML", "expected ',' or ']'"),
        text="simulation:\n  step_s: 0.1\n  end_s: [30\nnetwork: {net_file: x}\n",
    ),
    Case(
        "top_level_not_a_mapping",
        "<top level>",
        ("expected a mapping",),
        text="- simulation\n- network\n",
    ),
    Case("empty_file", "<top level>", ("expected a mapping",), text=""),
    Case(
        "file_not_utf8",
        "<top level>",
        ("UTF-8",),
        text=b"description: caf\xe9\nnetwork: {net_file: x}\n",
    ),
    # ------------------------------------------------------------------ files and network
    Case(
        "end_infinite",
        "simulation.end_s",
        ("finite",),
        put("simulation.end_s", float("inf")),
    ),
    Case(
        "missing_network_file",
        "network.net_file",
        ("file not found", "missing.net.xml"),
        put("network.net_file", "missing.net.xml"),
    ),
    Case(
        "net_file_and_sumocfg",
        "network.net_file",
        ("exactly one of network.net_file and network.sumocfg",),
        put("network.sumocfg", "x.sumocfg"),
    ),
    Case(
        "missing_route_file",
        "traffic.route_files[0]",
        ("file not found", "nowhere.rou.xml"),
        put("traffic.route_files", ["nowhere.rou.xml"]),
    ),
    Case(
        "unknown_edge",
        "platoons[0].route.edges[1]",
        ("unknown edge 'A1B1x'",),
        put("platoons.0.route.edges.1", "A1B1x"),
        hint="did you mean 'A1B1'?",
    ),
    Case(
        "unconnected_route",
        "platoons[0].route.edges[1]",
        ("edge 'left1A1' does not connect to 'B1B0'", "successors of 'left1A1'"),
        put("platoons.0.route.edges", ["left1A1", "B1B0"]),
    ),
    Case(
        "unknown_from_edge",
        "platoons[0].route.from_edge",
        ("unknown edge 'left1A9'",),
        put("platoons.0.route", {"from_edge": "left1A9", "to_edge": "A0left0"}),
        hint="did you mean 'left1A1'?",
    ),
    Case(
        "unknown_to_edge",
        "platoons[0].route.to_edge",
        ("unknown edge 'A0left9'",),
        put("platoons.0.route", {"from_edge": "left1A1", "to_edge": "A0left9"}),
        hint="did you mean 'A0left0'?",
    ),
    Case(
        "edges_and_from_edge",
        "platoons[0].route.edges",
        ("give either route.edges or route.from_edge + route.to_edge",),
        put("platoons.0.route.from_edge", "left1A1"),
    ),
    Case(
        "flow_unknown_edge",
        "traffic.flows[0].from_edge",
        ("unknown edge 'left1A9'",),
        put(
            "traffic.flows",
            [{"from_edge": "left1A9", "to_edge": "A0left0", "vehs_per_hour": 100}],
        ),
    ),
    Case(
        "flow_unknown_vehicle_type",
        "traffic.flows[0].type",
        ("unknown vehicle type 'truck'", "define it under traffic.vehicle_types", "car"),
        put(
            "traffic.flows",
            [{"from_edge": "left1A1", "to_edge": "A0left0", "vehs_per_hour": 100, "type": "truck"}],
        ),
    ),
    Case(
        "duplicate_vehicle_type_ids",
        "traffic.vehicle_types",
        ("duplicate", "car"),
        lambda d: d["traffic"]["vehicle_types"].append({"id": "car"}),
    ),
    Case(
        "vehicle_type_vclass_typo",
        "traffic.vehicle_types[0].vclass",
        ("pasenger",),
        put("traffic.vehicle_types.0.vclass", "pasenger"),
        hint="did you mean 'passenger'?",
    ),
    Case(
        "unknown_car_follow_model",
        "traffic.vehicle_types[0].car_follow_model",
        ("unknown value 'IMD'", "IDM"),
        put("traffic.vehicle_types.0.car_follow_model", "IMD"),
        hint="did you mean 'IDM'?",
    ),
    # ------------------------------------------------------------------ platoons
    Case(
        "leader_without_room",
        "platoons[0].depart_pos_m",
        ("front at 2.0 m", "4.5 m length", "edge 'left1A1'"),
        put("platoons.0.depart_pos_m", 2.0),
        hint="use at least 4.5",
    ),
    Case(
        "depart_pos_beyond_edge",
        "platoons[0].depart_pos_m",
        ("89.6",),
        put("platoons.0.depart_pos_m", 500.0),
    ),
    Case(
        "platoon_vclass_typo",
        "platoons[0].vehicle.vclass",
        ("pasenger",),
        put("platoons.0.vehicle.vclass", "pasenger"),
        hint="did you mean 'passenger'?",
    ),
    Case("zero_members", "platoons[0].members", ("must be >= 1",), put("platoons.0.members", 0)),
    Case(
        "depart_lane_out_of_range",
        "platoons[0].depart_lane",
        ("edge 'left1A1' has lanes 0..1, got 5",),
        put("platoons.0.depart_lane", 5),
    ),
    Case(
        "duplicate_platoon_ids",
        "platoons",
        ("duplicate platoon id(s): ego",),
        lambda d: d["platoons"].append(
            {**copy.deepcopy(d["platoons"][0]), "depart_s": 20},
        ),
    ),
    Case(
        "unknown_vehicle_model",
        "platoons[0].vehicle.model",
        ("unknown value 'bycicle'", "unicycle"),
        put("platoons.0.vehicle.model", "bycicle"),
        hint="did you mean 'bicycle'?",
    ),
    Case(
        "unknown_laser_preset",
        "platoons[0].leader.sensor.preset",
        ("unknown value 'utm30'", "utm30lx"),
        put("platoons.0.leader.sensor", {"preset": "utm30"}),
        hint="did you mean 'utm30lx'?",
    ),
    Case(
        "unknown_laser_override",
        "platoons[0].leader.sensor.overrides.noise_std",
        ("unknown laser setting", "noise_std_m"),
        put("platoons.0.leader.sensor", {"preset": "utm30lx", "overrides": {"noise_std": 0.01}}),
        hint="did you mean 'noise_std_m'?",
    ),
    # ------------------------------------------------------------------ controllers
    Case(
        "unknown_controller",
        "platoons[0].leader.type",
        ("unknown controller 'route_folowing'", "package.module:Class"),
        put("platoons.0.leader.type", "route_folowing"),
        hint="did you mean 'route_following'?",
    ),
    Case(
        "plugin_module_not_found",
        "platoons[0].leader.type",
        ("cannot import plug-in module 'no_such_plugin_pkg'", "ModuleNotFoundError"),
        put("platoons.0.leader.type", "no_such_plugin_pkg:Controller"),
    ),
    Case(
        "plugin_module_fails_to_import",
        "platoons[0].leader.type",
        ("cannot import plug-in module 'broken_controller'", "a_dependency_that_is_not_installed"),
        put("platoons.0.leader.type", "broken_controller:BrokenController"),
    ),
    Case(
        "plugin_attribute_missing",
        "platoons[0].leader.type",
        ("module 'my_controller' has no attribute 'NoSuchController'",),
        put("platoons.0.leader.type", "my_controller:NoSuchController"),
    ),
    Case(
        "plugin_not_a_controller",
        "platoons[0].leader.type",
        ("'my_controller:NotAController' is not a controller", "Params"),
        put("platoons.0.leader.type", "my_controller:NotAController"),
    ),
    Case(
        "plugin_params_not_a_dataclass",
        "platoons[0].leader.type",
        ("is not a controller", "dataclass"),
        put("platoons.0.leader.type", "my_controller:ParamsNotADataclass"),
    ),
    Case(
        "unknown_controller_param",
        "platoons[0].leader.params.comfort_decel",
        ("unknown key", "allowed:"),
        put("platoons.0.leader.params", {"comfort_decel": 2.0}),
        hint="did you mean 'comfort_decel_mps2'?",
    ),
    Case(
        "controller_param_out_of_range",
        "platoons[0].leader.params.comfort_decel_mps2",
        ("must be > 0",),
        put("platoons.0.leader.params", {"comfort_decel_mps2": -1.0}),
    ),
    Case(
        "follower_param_wrong_type",
        "platoons[0].follower.params.time_gap_s",
        ("expected a number", "'long'"),
        edits(
            put("platoons.0.members", 2),
            put("platoons.0.follower", {"params": {"time_gap_s": "long"}}),
        ),
    ),
    Case(
        "sumo_driver_unknown_model",
        "platoons[0].follower.params.car_follow_model",
        ("unknown value 'IMD'", "IDM", "Krauss", "CACC"),
        _sumo_followers({"car_follow_model": "IMD"}),
        hint="did you mean 'IDM'?",
    ),
    Case(
        "sumo_driver_parameter_of_another_model",
        "platoons[0].follower.params.parameters.speedControlGain",
        ("SUMO's IDM has no attribute 'speedControlGain'", "delta", "stepping"),
        _sumo_followers({"car_follow_model": "IDM", "parameters": {"speedControlGain": -0.4}}),
    ),
    Case(
        "sumo_driver_parameter_set_elsewhere",
        "platoons[0].follower.params.parameters.tau",
        ("is not a parameter here", "tau_s"),
        _sumo_followers({"car_follow_model": "Krauss", "parameters": {"tau": 1.0}}),
    ),
    Case(
        "sumo_driver_needs_lane_actuation",
        "platoons[0].actuation",
        ("controller 'sumo_driver' leaves the speed to SUMO's car-following model", "sublane"),
        _sumo_followers({}, actuation=None),  # cars' default: sublane
        hint="use `actuation: lane`",
    ),
    Case(
        "unknown_actuation",
        "platoons[0].actuation",
        ("'lanes'", "planar", "lane"),
        put("platoons.0.actuation", "lanes"),
        hint="did you mean 'lane'?",
    ),
    Case(
        "steered_platoon_without_sublane_model",
        "simulation.lateral_resolution_m",
        ("platoons[0] uses sublane actuation", "sublane model"),  # cars' default
        put("simulation.lateral_resolution_m", None),
        hint="actuation: lane",
    ),
    Case(
        "demand_scale_not_positive",
        "traffic.scale",
        ("must be > 0",),
        put("traffic.scale", 0),
    ),
]

# ---------------------------------------------------------------------- input limits (issue 12)

_BASE_TEXT = f"network: {{net_file: {NET.as_posix()}}}\n"


def _alias_bomb() -> str:
    """A "billion laughs": nine levels of nine aliases each, 9**9 strings if expanded."""
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for k in range(1, 10):
        lines.append(f"l{k}: &l{k} [" + ", ".join([f"*l{k - 1}"] * 9) + "]")
    return _BASE_TEXT + "description: x\n" + "\n".join(lines) + "\n"


#: A route file on the urban grid: a route, a vehicle with its own route, a trip, a flow.
_GOOD_ROUTES = """<routes>
  <route id="r0" edges="left1A1 A1B1"/>
  <vehicle id="v0" depart="0" route="r0"/>
  <vehicle id="v1" depart="triggered"><route edges="left1A1 A1B1"/></vehicle>
  <trip id="t0" depart="1:00" from="left1A1" to="A1B1"/>
  <flow id="f0" begin="0" end="20" from="left1A1" to="A1B1" number="3"/>
</routes>
"""


def _route_case(name: str, routes: str, expected: tuple[str, ...], hint: str | None = None) -> Case:
    return Case(
        name,
        "traffic.route_files[0]",
        ("cars.rou.xml", *expected),
        put("traffic.route_files", ["cars.rou.xml"]),
        hint=hint,
        files=(("cars.rou.xml", routes),),
    )


def _laser(overrides: dict[str, Any]) -> Edit:
    return put("platoons.0.leader.sensor", {"preset": "utm30lx", "overrides": overrides})


_SAFE_NAME = ("is not a safe name", "letters, digits")

LIMIT_CASES = [
    # YAML itself
    Case(
        "file_too_large",
        "<top level>",
        ("limited to 5 MB",),
        text=_BASE_TEXT + "# " + "x" * (5 * 2**20) + "\n",
    ),
    Case(
        "nesting_10000_deep_flow",
        "line 2",
        ("nesting",),  # libyaml's scanner or our limit, whichever notices first
        text=_BASE_TEXT + "description: " + "[" * 10_000 + "]" * 10_000 + "\n",
    ),
    Case(
        "nesting_10000_deep_block",
        "line 3",
        ("nesting deeper than 50 levels",),
        text=_BASE_TEXT + "description:\n" + "- " * 10_000 + "x\n",
    ),
    Case("alias_bomb", "line 8", ("aliases (*l4)", "more than 100000 nodes"), text=_alias_bomb()),
    Case(
        "duplicate_top_level_key",
        "simulation",
        ("key given twice", "lines 2 and 4"),
        text=_BASE_TEXT + "simulation: {end_s: 30}\nplatoons: []\nsimulation: {end_s: 60}\n",
    ),
    Case(
        "duplicate_nested_key",
        "platoons[0].route",
        ("key given twice", "lines 4 and 5"),
        text=_BASE_TEXT + "platoons:\n  - id: ego\n    route: {edges: [left1A1]}\n"
        "    route: {edges: [A1B1]}\n",
    ),
    Case(
        "python_tag_refused",
        "line 2",
        ("not valid YAML", "python/object/apply"),
        text=_BASE_TEXT + "description: !!python/object/apply:os.system ['echo hi']\n",
    ),
    # numbers
    Case(
        "begin_minus_infinity",
        "simulation.begin_s",
        ("expected a finite number", "-inf"),
        put("simulation.begin_s", float("-inf")),
    ),
    Case(
        "begin_negative",
        "simulation.begin_s",
        ("must be in [0, 10000000] s",),
        put("simulation.begin_s", -5),
    ),
    Case(
        "step_below_sumo_resolution",
        "simulation.step_s",
        ("must be in [0.001, 1] s", "1e-09"),
        put("simulation.step_s", 1e-9),
    ),
    Case(
        "seed_beyond_sumo_integers",
        "simulation.seed",
        ("must be in [0, 2147483647]",),
        put("simulation.seed", 2**70),
    ),
    Case(
        "end_integer_beyond_floats",
        "simulation.end_s",
        ("expected a finite number", "too large"),
        put("simulation.end_s", 10**400),
    ),
    Case(
        "end_absurdly_late",
        "simulation.end_s",
        ("must be in (0, 10000000] s",),
        put("simulation.end_s", 1e12),
    ),
    Case(
        "random_trips_end_1e308",
        "traffic.random_trips.end_s",
        ("must be in (0, 10000000] s", "1e+308"),
        put("traffic.random_trips", {"period_s": 2.0, "end_s": 1e308}),
    ),
    Case(
        "random_trips_end_after_simulation",
        "traffic.random_trips.end_s",
        ("after the simulation's end (30 s)",),
        put("traffic.random_trips", {"period_s": 2.0, "end_s": 100}),
        hint="simulation.end_s",
    ),
    Case(
        "random_trips_period_tiny",
        "traffic.random_trips.period_s",
        ("must be in [0.01, 10000000] s",),
        put("traffic.random_trips", {"period_s": 1e-9}),
    ),
    Case(
        "flow_end_after_simulation",
        "traffic.flows[0].end_s",
        ("after the simulation's end",),
        put(
            "traffic.flows",
            [{"from_edge": "left1A1", "to_edge": "A0left0", "vehs_per_hour": 100, "end_s": 1e6}],
        ),
    ),
    Case(
        "flow_rate_absurd",
        "traffic.flows[0].vehs_per_hour",
        ("must be in (0, 100000]",),
        put(
            "traffic.flows",
            [{"from_edge": "left1A1", "to_edge": "A0left0", "vehs_per_hour": 1e9}],
        ),
    ),
    Case(
        "laser_ten_million_samples",
        "platoons[0].leader.sensor.overrides.samples",
        ("an integer <= 20000", "10000000"),
        _laser({"samples": 10_000_000}),
    ),
    Case(
        "laser_noise_infinite",
        "platoons[0].leader.sensor.overrides.noise_std_m",
        ("expected a finite number", "inf"),
        _laser({"noise_std_m": float("inf")}),
    ),
    Case(
        "platoon_max_speed_1e308",
        "platoons[0].vehicle.max_speed_mps",
        ("must be in (0, 150] m/s", "1e+308"),
        put("platoons.0.vehicle.max_speed_mps", 1e308),
    ),
    Case(
        "platoon_vehicle_too_long",
        "platoons[0].vehicle.length_m",
        ("must be in (0, 50] m",),
        put("platoons.0.vehicle.length_m", 60),
    ),
    Case(
        "vehicle_type_speed_dev_nan",
        "traffic.vehicle_types[0].speed_dev",
        ("expected a finite number", "nan"),
        put("traffic.vehicle_types.0.speed_dev", float("nan")),
    ),
    Case(
        "vehicle_type_max_speed_huge",
        "traffic.vehicle_types[0].max_speed_mps",
        ("must be in (0, 150] m/s",),
        put("traffic.vehicle_types.0.max_speed_mps", 1e308),
    ),
    Case(
        "controller_param_nan",
        "platoons[0].leader.params.comfort_decel_mps2",
        ("expected a finite number", "nan"),
        put("platoons.0.leader.params", {"comfort_decel_mps2": float("nan")}),
    ),
    Case(
        "controller_param_out_of_upper_range",
        "platoons[0].leader.params.cruise_speed_mps",
        ("must be in (0, 150] m/s",),
        put("platoons.0.leader.params", {"cruise_speed_mps": 1000}),
    ),
    Case(
        "supervisor_decel_absurd",
        "platoons[0].supervisor.comfort_decel_mps2",
        ("must be in (0, 50] m/s²",),
        put("platoons.0.supervisor", {"comfort_decel_mps2": 1e6}),
    ),
    # names that become file names
    Case("scenario_name_escapes", "name", ("'../../x'", *_SAFE_NAME), put("name", "../../x")),
    Case(
        "platoon_id_with_slash",
        "platoons[0].id",
        ("'a/b'", *_SAFE_NAME),
        put("platoons.0.id", "a/b"),
    ),
    Case(
        "vehicle_type_id_with_slash",
        "traffic.vehicle_types[0].id",
        ("'c/d'", *_SAFE_NAME),
        put("traffic.vehicle_types.0.id", "c/d"),
    ),
    Case("platoon_id_too_long", "platoons[0].id", _SAFE_NAME, put("platoons.0.id", "p" * 65)),
    Case(
        "sensor_name_with_slash",
        "platoons[0].leader.sensors[0].name",
        ("'x/y'", *_SAFE_NAME),
        put("platoons.0.leader.sensors", [{"type": "laser", "name": "x/y"}]),
    ),
    Case(
        "v2v_unknown_param",
        "platoons[0].leader.sensors[0].params.delay",
        ("unknown key", "allowed:", "delay_s"),
        put("platoons.0.leader.sensors", [{"type": "v2v", "params": {"delay": 0.1}}]),
        hint="did you mean 'delay_s'?",
    ),
    Case(
        "v2v_burst_key_without_its_model",
        "platoons[0].leader.sensors[0].params.p_bad_to_good",
        ("only used with loss_model gilbert_elliott",),
        put("platoons.0.leader.sensors", [{"type": "v2v", "params": {"p_bad_to_good": 0.2}}]),
        hint="add `loss_model: gilbert_elliott`",
    ),
    # route and additional files
    _route_case(
        "route_file_unknown_edge",
        _GOOD_ROUTES.replace('left1A1 A1B1"/></vehicle>', 'left1A1 A1B9"/></vehicle>'),
        ("vehicle 'v1'", "unknown edge 'A1B9'"),
        hint="did you mean 'A1B1'?",
    ),
    _route_case(
        "route_file_trip_unknown_from",
        _GOOD_ROUTES.replace('from="left1A1" to="A1B1"/>', 'from="nowhere" to="A1B1"/>'),
        ("trip 't0'", "from: unknown edge 'nowhere'"),
    ),
    _route_case(
        "route_file_flow_nan_begin",
        _GOOD_ROUTES.replace('flow id="f0" begin="0"', 'flow id="f0" begin="nan"'),
        ("flow 'f0'", "begin='nan' is not a finite time"),
    ),
    _route_case(
        "route_file_not_well_formed",
        _GOOD_ROUTES[:120],
        ("cannot be read as XML", "not well-formed", "line 4"),
    ),
    Case(
        "additional_file_not_well_formed",
        "network.additional_files[0]",
        ("walls.add.xml", "cannot be read as XML", "not well-formed", "line 3"),
        put("network.additional_files", ["walls.add.xml"]),
        files=(
            (
                "walls.add.xml",
                '<additional>\n<poly id="w" type="wall" shape="0,0 1,1"/>\n<poly id="x" \n',
            ),
        ),
    ),
    Case(
        "additional_file_bad_shape",
        "network.additional_files[0]",
        ("walls.add.xml", "poly 'w'", "finite x,y points"),
        put("network.additional_files", ["walls.add.xml"]),
        files=(
            (
                "walls.add.xml",
                '<additional><poly id="w" type="wall" shape="0,0 a,b"/></additional>',
            ),
        ),
    ),
]

CASES += LIMIT_CASES

RUN_CASES = {
    "unknown_nested_key",
    "negative_step",
    "missing_network_file",
    "unknown_edge",
    "unconnected_route",
    "unknown_controller",
    "sumo_driver_unknown_model",
    "plugin_module_fails_to_import",
    "impossible_platoon",
    "duplicate_top_level_key",
    "alias_bomb",
    "step_below_sumo_resolution",
    "random_trips_end_1e308",
    "scenario_name_escapes",
    "route_file_unknown_edge",
    "route_file_flow_nan_begin",
    "additional_file_not_well_formed",
}


def _params(cases: list[Case]) -> list[Any]:
    return [pytest.param(c, id=c.id) for c in cases]


@pytest.fixture
def plugins_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))


def write_case(case: Case, directory: Path) -> Path:
    path = directory / FILE_NAME
    for name, content in case.files:
        (directory / name).write_text(content, encoding="utf-8")
    if case.missing_file:
        return path
    if case.text is not None:
        content = case.text
    else:
        data = valid_scenario()
        assert case.edit is not None
        case.edit(data)
        content = yaml.safe_dump(data, sort_keys=False)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def assert_one_line_error(err: str, case: Case) -> str:
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, f"expected exactly one line on stderr, got:\n{err}"
    line = lines[0]
    assert line.startswith("error: ")
    assert FILE_NAME in line
    assert f": {case.key}: " in line, f"key path {case.key!r} not named in: {line}"
    for fragment in case.expected:
        assert fragment in line, f"{fragment!r} not in: {line}"
    if case.hint is not None:
        assert case.hint in line, f"hint {case.hint!r} not in: {line}"
    return line


def test_valid_base_scenario_validates(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "good.yaml"
    path.write_text(yaml.safe_dump(valid_scenario(), sort_keys=False), encoding="utf-8")
    assert main(["validate", str(path)]) == 0
    out, err = capfd.readouterr()
    assert "OK (1 platoons, 1 vehicles" in out
    assert err == ""


@pytest.mark.usefixtures("plugins_on_path")
@pytest.mark.parametrize("case", _params(CASES))
def test_validate_rejects(case: Case, tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    path = write_case(case, tmp_path)
    code = main(["validate", str(path)])
    out, err = capfd.readouterr()
    assert code == 2, f"exit code {code}; stderr: {err}"
    assert out == ""
    assert_one_line_error(err, case)


@pytest.mark.usefixtures("plugins_on_path")
@pytest.mark.parametrize("case", _params([c for c in CASES if c.id in RUN_CASES]))
def test_run_rejects_before_starting(
    case: Case, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    path = write_case(case, tmp_path)
    out_dir = tmp_path / "out"
    code = main(["run", str(path), "--out", str(out_dir), "--quiet"])
    out, err = capfd.readouterr()
    assert code == 2, f"exit code {code}; stderr: {err}"
    assert out == ""
    assert_one_line_error(err, case)
    assert not (out_dir / "summary.json").exists()
    assert not out_dir.exists() or (out_dir / "FAILED.txt").exists()


def _run_with_end(tmp_path: Path, end: str) -> tuple[int, Path]:
    path = tmp_path / FILE_NAME
    path.write_text(yaml.safe_dump(valid_scenario(), sort_keys=False), encoding="utf-8")
    out_dir = tmp_path / "out"
    code = main(["run", str(path), "--out", str(out_dir), "--quiet", "--end", end])
    return code, out_dir


def test_run_rejects_bad_end_override(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    code, out_dir = _run_with_end(tmp_path, "-5")
    out, err = capfd.readouterr()
    assert code == 2
    assert out == ""
    assert_one_line_error(
        err, Case("end_override", "simulation.end_s", ("--end must be after begin_s",))
    )
    assert not (out_dir / "summary.json").exists()


def test_at_least_twelve_kinds_of_bad_input() -> None:
    assert len({c.id for c in CASES}) == len(CASES)
    assert len(CASES) >= 12


# ---------------------------------------------------------------------- user plug-ins


def _with_user_controller(params: dict[str, Any]) -> dict[str, Any]:
    data = valid_scenario()
    data["platoons"][0]["members"] = 2
    for role in ("leader", "follower"):
        data["platoons"][0][role] = {"type": "my_controller:MyController", "params": params}
    return data


@pytest.mark.usefixtures("plugins_on_path")
def test_user_plugin_validates(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "plugin.yaml"
    data = _with_user_controller({"gain": 2.0, "cruise_speed_mps": 3})
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    assert main(["validate", str(path)]) == 0
    out, err = capfd.readouterr()
    assert "OK (1 platoons, 2 vehicles" in out
    assert err == ""


@pytest.mark.usefixtures("plugins_on_path")
def test_user_plugin_plan_holds_its_params(tmp_path: Path) -> None:
    from platoon_sumo.scenario import load_scenario, prepare

    path = tmp_path / "plugin.yaml"
    data = _with_user_controller({"gain": 2.0, "cruise_speed_mps": 3})
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    plan = prepare(load_scenario(path))
    members = plan.platoons[0].members
    assert [m.controller_cls.__name__ for m in members] == ["MyController"] * 2
    params = members[0].controller_params
    assert type(params).__name__ == "MyParams"
    assert (params.gain, params.cruise_speed_mps) == (2.0, 3.0)


@pytest.mark.usefixtures("plugins_on_path")
@pytest.mark.parametrize(
    ("params", "key", "expected", "hint"),
    [
        ({"gian": 2.0}, "platoons[0].leader.params.gian", "unknown key", "did you mean 'gain'?"),
        ({"gain": -1.0}, "platoons[0].leader.params.gain", "must be > 0", None),
        ({"gain": "high"}, "platoons[0].leader.params.gain", "expected a number", None),
    ],
    ids=["unknown_key", "out_of_range", "wrong_type"],
)
def test_user_plugin_params_are_checked(
    params: dict[str, Any],
    key: str,
    expected: str,
    hint: str | None,
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
) -> None:
    path = tmp_path / FILE_NAME
    path.write_text(yaml.safe_dump(_with_user_controller(params)), encoding="utf-8")
    assert main(["validate", str(path)]) == 2
    _, err = capfd.readouterr()
    assert_one_line_error(err, Case("plugin_params", key, (expected,), hint=hint))


def test_integer_laser_override_is_accepted(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    data = valid_scenario()
    data["platoons"][0]["leader"]["sensor"] = {"preset": "utm30lx", "overrides": {"samples": 500}}
    path = tmp_path / "sensor.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    code = main(["validate", str(path)])
    _, err = capfd.readouterr()
    assert code == 0, err


# ---------------------------------------------------------------------- limits: cost, shipped files


@pytest.mark.parametrize(
    "text",
    [_alias_bomb(), _BASE_TEXT + "description:\n" + "- " * 10_000 + "x\n"],
    ids=["alias_bomb", "deep_nesting"],
)
def test_hostile_yaml_is_refused_quickly_in_little_memory(tmp_path: Path, text: str) -> None:
    import time
    import tracemalloc

    from platoon_sumo.errors import ScenarioError
    from platoon_sumo.scenario import load_scenario

    path = tmp_path / FILE_NAME
    path.write_text(text, encoding="utf-8")
    tracemalloc.start()
    started = time.perf_counter()
    try:
        with pytest.raises(ScenarioError):
            load_scenario(path)
        elapsed = time.perf_counter() - started
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert elapsed < 2.0
    assert peak < 50 * 2**20


def test_run_rejects_seed_override_beyond_sumo(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / FILE_NAME
    path.write_text(yaml.safe_dump(valid_scenario(), sort_keys=False), encoding="utf-8")
    out_dir = tmp_path / "out"
    code = main(["run", str(path), "--out", str(out_dir), "--quiet", "--seed", str(2**40)])
    _, err = capfd.readouterr()
    assert code == 2
    assert_one_line_error(
        err, Case("seed_override", "simulation.seed", ("--seed must be in [0, 2147483647]",))
    )
    assert not (out_dir / "summary.json").exists()


def test_default_name_from_an_unsafe_file_name_is_made_safe(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    from platoon_sumo.scenario import load_scenario

    path = tmp_path / "my scenario (v2).yaml"
    path.write_text(yaml.safe_dump(valid_scenario(), sort_keys=False), encoding="utf-8")
    assert load_scenario(path).scenario.name == "my_scenario__v2"


def test_route_file_that_is_fine_validates(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    data = valid_scenario()
    data["traffic"]["route_files"] = ["cars.rou.xml"]
    (tmp_path / "cars.rou.xml").write_text(_GOOD_ROUTES, encoding="utf-8")
    path = tmp_path / "good.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    code = main(["validate", str(path)])
    _, err = capfd.readouterr()
    assert code == 0, err


@pytest.mark.parametrize(
    "scenario",
    sorted((ROOT / "scenarios").rglob("*.yaml")),
    ids=lambda p: str(p.relative_to(ROOT / "scenarios").with_suffix("")),
)
@pytest.mark.slow
def test_shipped_scenarios_validate(scenario: Path, capfd: pytest.CaptureFixture[str]) -> None:
    code = main(["validate", str(scenario)])
    _, err = capfd.readouterr()
    assert code == 0, err
    assert "error" not in err
