"""`load_dataclass`: strict typed loading of parsed YAML into frozen dataclasses."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import pytest

from platoon_sumo.config_loader import (
    Bounds,
    FieldError,
    bounded,
    field_bounds,
    load_dataclass,
    require,
)
from platoon_sumo.errors import ScenarioError

FILE = "test.yaml"


@dataclass(frozen=True)
class Point:
    x: float
    y: float = 0.0


@dataclass(frozen=True)
class Shape:
    name: str
    points: tuple[Point, ...] = ()
    kind: Literal["polygon", "polyline"] = "polygon"
    closed: bool = True
    count: int = 1
    tags: Mapping[str, float] = field(default_factory=dict)
    color: str | None = None
    scale: float | None = None
    anchor: Point | None = None
    extra: Any = None

    def __post_init__(self) -> None:
        require(self.count >= 1, "count", "must be >= 1")
        require(len(self.points) != 1, "points", "needs no or at least 2 points", "add a point")


@dataclass(frozen=True)
class Drawing:
    shapes: tuple[Shape, ...] = ()
    origin: Point = Point(0.0)
    label: int | str | None = None


@dataclass(frozen=True)
class Interval:
    low: float
    high: float

    def __post_init__(self) -> None:
        if self.high <= self.low:
            raise ValueError("high must be above low")


@dataclass(frozen=True)
class Window:
    interval: Interval


@dataclass(frozen=True)
class Numbers:
    values: Mapping[str, float | int] = field(default_factory=dict)


def load(cls: type[Any], data: Any, path: str = "") -> Any:
    return load_dataclass(cls, data, FILE, path)


def error(cls: type[Any], data: Any, path: str = "") -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load(cls, data, path)
    return info.value


# ---------------------------------------------------------------------- valid input


def test_loads_nested_dataclasses() -> None:
    drawing = load(
        Drawing,
        {
            "shapes": [
                {"name": "a", "points": [{"x": 1, "y": 2.5}, {"x": 3}], "kind": "polyline"},
                {"name": "b", "closed": False, "count": 3, "tags": {"w": 2}},
            ],
            "origin": {"x": -1.0},
            "label": "title",
        },
    )
    assert drawing == Drawing(
        shapes=(
            Shape("a", (Point(1.0, 2.5), Point(3.0)), kind="polyline"),
            Shape("b", closed=False, count=3, tags={"w": 2.0}),
        ),
        origin=Point(-1.0),
        label="title",
    )
    assert isinstance(drawing.shapes, tuple)
    assert isinstance(drawing.shapes[0].points, tuple)
    with pytest.raises(dataclasses.FrozenInstanceError):
        drawing.label = "x"  # type: ignore[misc]


def test_defaults_apply_to_missing_optional_keys() -> None:
    assert load(Drawing, {}) == Drawing()
    shape = load(Shape, {"name": "s"})
    assert (shape.color, shape.scale, shape.anchor, shape.kind) == (None, None, None, "polygon")


def test_int_is_accepted_as_float() -> None:
    point = load(Point, {"x": 1, "y": -2})
    assert point == Point(1.0, -2.0)
    assert type(point.x) is float and type(point.y) is float


def test_optional_accepts_null_and_the_type() -> None:
    shape = load(Shape, {"name": "s", "color": None, "scale": 2, "anchor": {"x": 1}})
    assert shape.color is None
    assert shape.scale == 2.0 and type(shape.scale) is float
    assert shape.anchor == Point(1.0)


def test_union_of_two_types() -> None:
    assert load(Drawing, {"label": 5}).label == 5
    assert load(Drawing, {"label": "five"}).label == "five"
    err = error(Drawing, {"label": 5.5})
    assert err.key_path == "label"
    assert err.message == "expected an integer or a string, got 5.5 (float)"


def test_mapping_is_read_only_with_converted_values() -> None:
    shape = load(Shape, {"name": "s", "tags": {"w": 1, "h": 2.5}})
    assert dict(shape.tags) == {"w": 1.0, "h": 2.5}
    assert isinstance(shape.tags, Mapping)
    with pytest.raises(TypeError):
        shape.tags["w"] = 3.0  # type: ignore[index]


def test_any_passes_through() -> None:
    assert load(Shape, {"name": "s", "extra": [1, {"a": None}]}).extra == [1, {"a": None}]


def test_literal_accepts_its_values() -> None:
    assert load(Shape, {"name": "s", "kind": "polyline"}).kind == "polyline"


# ---------------------------------------------------------------------- wrong types


@pytest.mark.parametrize(
    ("data", "key", "message"),
    [
        ({"x": True}, "x", "expected a number, got True (bool)"),
        ({"x": "1.0"}, "x", "expected a number, got '1.0' (str)"),
        ({"x": None}, "x", "expected a number, got None (NoneType)"),
        ({"x": [1]}, "x", "expected a number, got a list"),
        ({"x": 0, "y": {"v": 1}}, "y", "expected a number, got a mapping"),
    ],
    ids=["bool", "string", "null", "list", "mapping"],
)
def test_number_rejects(data: dict[str, Any], key: str, message: str) -> None:
    err = error(Point, data)
    assert (err.file, err.key_path, err.message, err.hint) == (FILE, key, message, None)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (True, "expected an integer, got True (bool)"),
        (2.0, "expected an integer, got 2.0 (float)"),
        ("2", "expected an integer, got '2' (str)"),
    ],
    ids=["bool", "float", "string"],
)
def test_integer_rejects(value: Any, message: str) -> None:
    err = error(Shape, {"name": "s", "count": value})
    assert (err.key_path, err.message) == ("count", message)


@pytest.mark.parametrize("value", [1, 0, "yes", None], ids=["one", "zero", "yes", "null"])
def test_bool_accepts_only_true_or_false(value: Any) -> None:
    err = error(Shape, {"name": "s", "closed": value})
    assert err.key_path == "closed"
    assert err.message.startswith("expected true or false, got ")


def test_string_rejects_a_number() -> None:
    err = error(Shape, {"name": 7})
    assert (err.key_path, err.message) == ("name", "expected a string, got 7 (int)")


def test_optional_rejects_the_wrong_type() -> None:
    err = error(Shape, {"name": "s", "color": 5})
    assert (err.key_path, err.message) == ("color", "expected a string, got 5 (int)")
    err = error(Shape, {"name": "s", "scale": "big"})
    assert (err.key_path, err.message) == ("scale", "expected a number, got 'big' (str)")


def test_optional_dataclass_reports_the_inner_key() -> None:
    err = error(Shape, {"name": "s", "anchor": {"x": "left"}})
    assert err.key_path == "anchor.x"
    assert err.message == "expected a number, got 'left' (str)"


def test_literal_rejects_other_values_with_a_suggestion() -> None:
    err = error(Shape, {"name": "s", "kind": "polygone"})
    assert err.key_path == "kind"
    assert err.message == "expected one of 'polygon', 'polyline', got 'polygone' (str)"
    assert err.hint == "did you mean 'polygon'?"
    err = error(Shape, {"name": "s", "kind": "circle"})
    assert err.hint is None


def test_tuple_rejects_a_scalar_and_a_mapping() -> None:
    err = error(Shape, {"name": "s", "points": {"x": 1}})
    assert (err.key_path, err.message) == ("points", "expected a list, got a mapping")
    err = error(Shape, {"name": "s", "points": "p1"})
    assert (err.key_path, err.message) == ("points", "expected a list, got 'p1' (str)")


def test_mapping_rejects_a_list_and_reports_bad_values_at_their_key() -> None:
    err = error(Shape, {"name": "s", "tags": ["w"]})
    assert (err.key_path, err.message) == ("tags", "expected a mapping, got a list")
    err = error(Shape, {"name": "s", "tags": {"w": "wide"}})
    assert (err.key_path, err.message) == ("tags.w", "expected a number, got 'wide' (str)")
    err = error(Shape, {"name": "s", "tags": {3: 1.0}})
    assert (err.key_path, err.message) == ("tags.3", "expected a string, got 3 (int)")


def test_dataclass_rejects_a_non_mapping() -> None:
    err = error(Drawing, {"origin": [1, 2]})
    assert (err.key_path, err.message) == ("origin", "expected a mapping, got a list")
    err = error(Drawing, "shapes")
    assert (err.key_path, err.message) == ("", "expected a mapping, got 'shapes' (str)")


# ---------------------------------------------------------------------- keys


def test_unknown_key_with_suggestion() -> None:
    err = error(Shape, {"nmae": "s"})
    assert err.key_path == "nmae"
    assert err.message.startswith("unknown key (allowed: name, points, kind, closed, count,")
    assert err.hint == "did you mean 'name'?"


def test_unknown_key_without_close_match() -> None:
    err = error(Point, {"x": 1, "zzz": 2})
    assert (err.key_path, err.message, err.hint) == ("zzz", "unknown key (allowed: x, y)", None)


def test_missing_required_key() -> None:
    err = error(Drawing, {"shapes": [{"name": "a"}, {"points": []}]})
    assert (err.key_path, err.message) == ("shapes[1].name", "required key is missing")
    err = error(Point, {"y": 1})
    assert (err.key_path, err.message) == ("x", "required key is missing")


def test_list_index_in_the_path() -> None:
    data = {
        "shapes": [
            {"name": "a"},
            {"name": "b", "points": [{"x": 0}, {"x": 1}, {"x": 2, "y": False}]},
        ]
    }
    err = error(Drawing, data)
    assert err.key_path == "shapes[1].points[2].y"
    assert err.message == "expected a number, got False (bool)"


def test_path_prefix_is_prepended() -> None:
    err = error(Point, {"x": "a"}, path="platoons[0].leader.params")
    assert err.key_path == "platoons[0].leader.params.x"
    err = error(Point, {"q": 1}, path="section")
    assert err.key_path == "section.q"


# ---------------------------------------------------------------------- range checks


def test_field_error_from_post_init_names_the_key() -> None:
    err = error(Drawing, {"shapes": [{"name": "a"}, {"name": "b", "count": 0}]})
    assert (err.key_path, err.message, err.hint) == ("shapes[1].count", "must be >= 1", None)


def test_field_error_keeps_its_hint() -> None:
    err = error(Drawing, {"shapes": [{"name": "a", "points": [{"x": 1}]}]})
    assert err.key_path == "shapes[0].points"
    assert err.message == "needs no or at least 2 points"
    assert err.hint == "add a point"


def test_plain_value_error_is_reported_at_the_dataclass() -> None:
    err = error(Window, {"interval": {"low": 2, "high": 1}})
    assert (err.key_path, err.message) == ("interval", "high must be above low")


def test_require() -> None:
    require(True, "k", "never raised")
    with pytest.raises(FieldError) as info:
        require(False, "k", "must be > 0", "try 1")
    assert (info.value.key, info.value.message, info.value.hint) == ("k", "must be > 0", "try 1")
    assert isinstance(info.value, ValueError)


def test_scenario_error_text() -> None:
    err = error(Drawing, {"shapes": [{"nmae": "a"}]})
    assert str(err).startswith(f"{FILE}: shapes[0].nmae: unknown key (allowed: ")
    assert str(err).endswith(" (did you mean 'name'?)")
    assert str(ScenarioError(FILE, "", "not found")) == f"{FILE}: <top level>: not found"


# ---------------------------------------------------------------------- known shortcomings


def test_union_keeps_an_int_as_int() -> None:
    numbers = load(Numbers, {"values": {"samples": 5, "noise": 0.1}})
    assert type(numbers.values["samples"]) is int
    assert type(numbers.values["noise"]) is float


# ---------------------------------------------------------------------- finite numbers, ranges


@dataclass(frozen=True)
class Ranged:
    speed_mps: float = bounded(1.0, gt=0, le=150)
    count: int = bounded(1, ge=1, le=10)
    limit_m: float = bounded(math.inf, gt=0, le=100, allow_inf=True)
    anything: float = 0.0
    mixed: Mapping[str, float | int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        require(self.speed_mps != 99, "speed_mps", "own check first")


@pytest.mark.parametrize(
    ("data", "key", "message"),
    [
        ({"anything": float("nan")}, "anything", "expected a finite number, got nan"),
        ({"anything": float("inf")}, "anything", "expected a finite number, got inf"),
        ({"anything": 10**400}, "anything", "too large"),
        ({"mixed": {"a": float("nan")}}, "mixed.a", "expected a finite number"),
        ({"speed_mps": 0}, "speed_mps", "must be in (0, 150] m/s, got 0.0"),
        ({"speed_mps": 1e308}, "speed_mps", "must be in (0, 150] m/s"),
        ({"count": 11}, "count", "must be in [1, 10], got 11"),
        ({"limit_m": float("nan")}, "limit_m", "expected a finite number, got nan"),
        ({"limit_m": 101}, "limit_m", "must be in (0, 100] m"),
        ({"speed_mps": 99}, "speed_mps", "own check first"),
    ],
)
def test_numbers_are_finite_and_within_their_range(data: Any, key: str, message: str) -> None:
    exc = error(Ranged, data)
    assert exc.key_path == key
    assert message in exc.message


def test_a_field_may_allow_infinity() -> None:
    assert load(Ranged, {"limit_m": float("inf")}).limit_m == math.inf
    assert load(Ranged, {}).limit_m == math.inf


def test_bounds_are_readable() -> None:
    f = {f.name: f for f in dataclasses.fields(Ranged)}
    assert field_bounds(f["speed_mps"]) == Bounds(gt=0, le=150, unit="m/s")
    assert Bounds(ge=0.001, le=1, unit="s").describe() == "in [0.001, 1] s"
    assert Bounds(ge=0).describe() == ">= 0"
    assert field_bounds(f["anything"]) is None
