"""Strict, typed loading of YAML mappings into frozen dataclasses.

Every dataclass field is a key; unknown keys fail with a "did you mean", wrong types
and failed range checks (ValueError raised in ``__post_init__``) fail with the key path.
The schema is the dataclasses themselves, so docs and validation cannot drift apart.

Numbers are finite: NaN is refused everywhere, and so are infinities unless the field's
metadata says it means "unbounded" (`field(metadata=ALLOW_INF)`). A field declared with
`bounded(...)` carries its allowed range in its metadata; the loader checks it after the
dataclass's own `__post_init__` (whose messages come first) and the reference generator
(tools/scenario_reference.py) prints it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar, Union, get_args, get_origin, get_type_hints

from platoon_sumo.errors import ScenarioError, did_you_mean

T = TypeVar("T")

_TYPE_WORDS = {int: "an integer", float: "a number", str: "a string", bool: "true or false"}


#: Field metadata: this number may be `.inf` / `-.inf` (it means "unbounded"); NaN never.
ALLOW_INF: Mapping[str, Any] = types.MappingProxyType({"allow_inf": True})

_UNITS = (
    ("_mps2", "m/s²"), ("_radps", "rad/s"), ("_mps", "m/s"), ("_hz", "Hz"), ("_rad", "rad"),
    ("_deg", "°"), ("_m", "m"), ("_s", "s"),
)  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Bounds:
    """Allowed range of a numeric field (None: no bound on that side)."""

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    unit: str = ""

    def contains(self, value: float) -> bool:
        return not (
            (self.ge is not None and not value >= self.ge)
            or (self.gt is not None and not value > self.gt)
            or (self.le is not None and not value <= self.le)
            or (self.lt is not None and not value < self.lt)
        )

    def describe(self) -> str:
        """E.g. `in [0.001, 1] s`, `> 0 m`, `<= 150 m/s`."""
        low = (f"[{_num(self.ge)}", ">=", self.ge) if self.ge is not None else None
        low = (f"({_num(self.gt)}", ">", self.gt) if self.gt is not None else low
        high = (f"{_num(self.le)}]", "<=", self.le) if self.le is not None else None
        high = (f"{_num(self.lt)})", "<", self.lt) if self.lt is not None else high
        unit = f" {self.unit}" if self.unit else ""
        if low and high:
            return f"in {low[0]}, {high[0]}{unit}"
        one = low or high
        return f"{one[1]} {_num(one[2])}{unit}" if one else "any number"


def _num(value: float | None) -> str:
    assert value is not None
    if isinstance(value, int) or float(value).is_integer():
        return str(int(value))
    return format(value, ".10g")


def bounded(
    default: Any = dataclasses.MISSING,
    *,
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    unit: str | None = None,
    allow_inf: bool = False,
) -> Any:
    """A dataclass field with an allowed range, checked by the loader and documented.

    `unit` defaults to the one the field name ends in (`_s`, `_m`, `_mps`, ...), found
    when the class is loaded (the name is not known here)."""
    meta: dict[str, Any] = {"bounds": Bounds(ge, gt, le, lt, unit or "")}
    if unit is None:
        meta["unit_from_name"] = True
    if allow_inf:
        meta["allow_inf"] = True
    return dataclasses.field(default=default, metadata=meta)


def field_bounds(f: dataclasses.Field[Any]) -> Bounds | None:
    """The range declared with `bounded` for a field, its unit filled in from the name."""
    found = f.metadata.get("bounds")
    if found is None or not f.metadata.get("unit_from_name"):
        return typing.cast("Bounds | None", found)
    unit = next((u for suffix, u in _UNITS if f.name.endswith(suffix)), "")
    return dataclasses.replace(found, unit=unit)


def check_bounds(obj: object) -> None:
    """Raise FieldError for the first field of a dataclass instance outside its `bounded`
    range (None values, i.e. "not set", pass)."""
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        bounds = field_bounds(f)
        value = getattr(obj, f.name)
        if bounds is None or value is None or isinstance(value, bool | str):
            continue
        if isinstance(value, int | float) and math.isinf(value) and f.metadata.get("allow_inf"):
            continue
        if not isinstance(value, int | float) or not bounds.contains(value):
            raise FieldError(f.name, f"must be {bounds.describe()}, got {value!r}")


class FieldError(ValueError):
    """A range/consistency error found inside a dataclass, tied to one of its keys."""

    def __init__(self, key: str, message: str, hint: str | None = None):
        super().__init__(message)
        self.key = key
        self.message = message
        self.hint = hint


def load_dataclass(cls: type[T], data: Any, file: str, path: str = "") -> T:
    """Build `cls` from `data` (parsed YAML), raising ScenarioError at the first problem."""
    return typing.cast(T, _convert(cls, data, file, path))


def _join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _describe(tp: Any) -> str:
    if tp in _TYPE_WORDS:
        return _TYPE_WORDS[tp]
    origin = get_origin(tp)
    if origin is typing.Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if origin in (list, tuple):
        return "a list"
    if origin in (dict, Mapping):
        return "a mapping"
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    if origin in (Union, types.UnionType):
        return " or ".join(_describe(a) for a in get_args(tp) if a is not type(None))
    return getattr(tp, "__name__", str(tp))


def _convert(tp: Any, value: Any, file: str, path: str, finite: bool = True) -> Any:
    origin = get_origin(tp)
    if tp is Any:
        if isinstance(value, float) and not math.isfinite(value):
            raise ScenarioError(file, path, f"expected a finite number, got {value!r}")
        return value
    if origin in (Union, types.UnionType):
        options = get_args(tp)
        if value is None and type(None) in options:
            return None
        if type(value) in options:  # an exact match wins: `float | int` keeps ints as ints
            return _convert(type(value), value, file, path, finite)
        errors: list[ScenarioError] = []
        for option in options:
            if option is type(None):
                continue
            try:
                return _convert(option, value, file, path, finite)
            except ScenarioError as exc:
                errors.append(exc)
        if len(errors) == 1:
            raise errors[0]
        raise ScenarioError(file, path, f"expected {_describe(tp)}, got {_show(value)}")
    if origin is typing.Literal:
        allowed = get_args(tp)
        if value not in allowed:
            hint = did_you_mean(str(value), [str(a) for a in allowed])
            raise ScenarioError(file, path, f"expected {_describe(tp)}, got {_show(value)}", hint)
        return value
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return _convert_dataclass(tp, value, file, path)
    if origin is tuple:
        args = get_args(tp)
        if not isinstance(value, list | tuple):
            raise ScenarioError(file, path, f"expected a list, got {_show(value)}")
        item_type = args[0] if args else Any
        return tuple(
            _convert(item_type, v, file, _join(path, i), finite) for i, v in enumerate(value)
        )
    if origin in (dict, Mapping):
        key_type, value_type = get_args(tp) or (str, Any)
        if not isinstance(value, Mapping):
            raise ScenarioError(file, path, f"expected a mapping, got {_show(value)}")
        return types.MappingProxyType(
            {
                _convert(key_type, k, file, _join(path, str(k))): _convert(
                    value_type, v, file, _join(path, str(k)), finite
                )
                for k, v in value.items()
            }
        )
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ScenarioError(file, path, f"expected a number, got {_show(value)}")
        try:
            number = float(value)
        except OverflowError:  # an integer beyond the range of floats
            number = math.inf
        if not math.isfinite(number) and (finite or math.isnan(number)):
            shown = "an integer too large for a number" if isinstance(value, int) else repr(value)
            raise ScenarioError(file, path, f"expected a finite number, got {shown}")
        return number
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ScenarioError(file, path, f"expected an integer, got {_show(value)}")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise ScenarioError(file, path, f"expected true or false, got {_show(value)}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ScenarioError(file, path, f"expected a string, got {_show(value)}")
        return value
    raise TypeError(f"unsupported schema type {tp!r} at {path}")  # a bug in our schema


@functools.cache
def _schema(cls: type) -> tuple[dict[str, Any], dict[str, dataclasses.Field[Any]]]:
    """A dataclass's resolved field types and init fields, worked out once per class
    (resolving the annotations took about 3 ms per platoon of a scenario)."""
    return get_type_hints(cls), {f.name: f for f in dataclasses.fields(cls) if f.init}


def _convert_dataclass(cls: type, value: Any, file: str, path: str) -> Any:
    if not isinstance(value, Mapping):
        raise ScenarioError(file, path, f"expected a mapping, got {_show(value)}")
    hints, fields = _schema(cls)
    for key in value:
        if key not in fields:
            hint = did_you_mean(str(key), fields)
            allowed = ", ".join(fields)
            raise ScenarioError(
                file, _join(path, str(key)), f"unknown key (allowed: {allowed})", hint
            )
    kwargs: dict[str, Any] = {}
    for name, field in fields.items():
        if name in value:
            finite = not field.metadata.get("allow_inf", False)
            kwargs[name] = _convert(hints[name], value[name], file, _join(path, name), finite)
        elif field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
            raise ScenarioError(file, _join(path, name), "required key is missing")
    try:
        built = cls(**kwargs)
        check_bounds(built)
        return built
    except FieldError as exc:
        raise ScenarioError(file, _join(path, exc.key), exc.message, exc.hint) from None
    except ValueError as exc:
        raise ScenarioError(file, path, str(exc)) from None


def _show(value: Any) -> str:
    if isinstance(value, Mapping):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return f"{value!r} ({type(value).__name__})"


def require(condition: bool, key: str, message: str, hint: str | None = None) -> None:
    """Range check for `__post_init__`: raises FieldError naming the key."""
    if not condition:
        raise FieldError(key, message, hint)


def require_positive(config: object, *keys: str, allow_zero: bool = False) -> None:
    """Each named field of `config` must be > 0 (>= 0 with `allow_zero`); NaN fails too."""
    for key in keys:
        value = getattr(config, key)
        ok = value >= 0 if allow_zero else value > 0
        require(bool(ok), key, "must be >= 0" if allow_zero else "must be > 0")


def require_choice(value: str, choices: Sequence[str], key: str) -> None:
    """`value` must be one of `choices`; otherwise name them and suggest the closest."""
    if value not in choices:
        raise FieldError(
            key,
            f"unknown value '{value}' (expected one of: {', '.join(choices)})",
            did_you_mean(value, choices),
        )
