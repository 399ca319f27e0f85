"""Bounded YAML reading for files users give us (scenario files).

`yaml.safe_load` builds only plain data (no `!!python` tags), but it trusts the file's
size and shape: a 10,000-deep nesting ends in a RecursionError, an alias bomb ("billion
laughs") in minutes of work and gigabytes, and a key given twice silently keeps the last
value. `load_bounded` reads with the same safe constructor and refuses, before building
any data:

- nesting deeper than `MAX_DEPTH` collections;
- more than `MAX_ALIAS_NODES` nodes produced through aliases (`*name`), counting every
  node of the anchored subtree each time an alias repeats it;
- a key given twice in one mapping (merge keys `<<:` may still be overridden).

`read_mapping` reads a file users give us with these limits, its size (`MAX_BYTES`)
and encoding checked first, into a mapping, or raises one `ScenarioError` naming it.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.events import AliasEvent
from yaml.nodes import MappingNode, Node, ScalarNode

from platoon_sumo.errors import ScenarioError

#: Largest scenario file read [bytes].
MAX_BYTES = 5 * 1024 * 1024
#: Deepest nesting of mappings and lists.
MAX_DEPTH = 50
#: Most nodes that aliases may repeat in one file.
MAX_ALIAS_NODES = 100_000

_Base: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class YamlLimitError(Exception):
    """The file breaks one of the limits; `where` is a key path or `line N`."""

    def __init__(self, where: str, message: str):
        super().__init__(message)
        self.where = where
        self.message = message


class _BoundedLoader(Composer, _Base):
    """A safe loader whose (Python) composer counts depth and aliased nodes and checks
    keys; libyaml still does the scanning and parsing when it is installed."""

    def __init__(self, stream: str) -> None:
        _Base.__init__(self, stream)
        self.anchors: dict[str, Node] = {}
        self._path: list[str | int] = []
        self._sizes: dict[int, int] = {}
        self._counts: list[int] = [0]
        self._aliased = 0

    # Composer.compose_node(parent, index): index is the key node of a mapping's value,
    # the position in a sequence, or None (a key, or the document's root).
    def compose_node(self, parent: Node | None, index: Any) -> Node | None:
        step: str | int | None = None
        if isinstance(index, ScalarNode):
            step = str(index.value)
        elif isinstance(index, int):
            step = index
        if self.check_event(AliasEvent):
            event = self.peek_event()
            node = super().compose_node(parent, index)
            size = self._sizes.get(id(node), 1)
            self._aliased += size
            if self._aliased > MAX_ALIAS_NODES:
                raise YamlLimitError(
                    f"line {event.start_mark.line + 1}",
                    f"aliases (*{event.anchor}) repeat more than {MAX_ALIAS_NODES} nodes "
                    "(an alias bomb?); write the data out or use fewer aliases",
                )
            self._counts[-1] += size
            return node
        if step is not None:
            self._path.append(step)
        if len(self._path) > MAX_DEPTH:
            event = self.peek_event()
            raise YamlLimitError(
                f"line {event.start_mark.line + 1}",
                f"nesting deeper than {MAX_DEPTH} levels",
            )
        self._counts.append(0)
        node = super().compose_node(parent, index)
        size = 1 + self._counts.pop()
        self._counts[-1] += size
        if getattr(node, "value", None) is not None and not isinstance(node, ScalarNode):
            self._sizes[id(node)] = size
        if isinstance(node, MappingNode):
            self._check_keys(node)
        if step is not None:
            self._path.pop()
        return node

    def _check_keys(self, node: MappingNode) -> None:
        seen: dict[tuple[str, str], int] = {}
        for key, _ in node.value:
            if not isinstance(key, ScalarNode) or key.tag == "tag:yaml.org,2002:merge":
                continue
            line = key.start_mark.line + 1
            first = seen.get((key.tag, key.value))
            seen[(key.tag, key.value)] = line
            if first is not None:
                raise YamlLimitError(
                    _path_text([*self._path, str(key.value)]),
                    f"key given twice in one mapping (lines {first} and {line}); "
                    "the second would silently replace the first",
                )


def _path_text(parts: list[str | int]) -> str:
    out = ""
    for part in parts:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else part
    return out


def load_bounded(text: str) -> Any:
    """Parse one YAML document within the limits; raises YamlLimitError or yaml.YAMLError."""
    loader = _BoundedLoader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


def read_mapping(path: Path, shown: str, what: str = "scenario") -> tuple[str, Mapping[str, Any]]:
    """(text, the YAML mapping) of `path`, a `what` file (`shown` names it in errors),
    read with the limits above; ScenarioError for a missing, large, non-UTF-8, invalid or
    non-mapping file."""
    if not path.is_file():
        raise ScenarioError(shown, "", f"{what} file not found", "check the path")
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise ScenarioError(
            shown, "", f"file is {size / 2**20:.1f} MB; {what} files are limited to "
            f"{MAX_BYTES // 2**20} MB", "put large data in route or additional files",
        )  # fmt: skip
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(
            shown, "", f"not UTF-8 text ({exc.reason} at byte {exc.start})"
        ) from None
    try:
        data = load_bounded(text)
    except YamlLimitError as exc:
        raise ScenarioError(shown, exc.where, exc.message) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark else ""
        raise ScenarioError(
            shown, where, f"not valid YAML: {getattr(exc, 'problem', exc)}"
        ) from None
    if not isinstance(data, Mapping):
        raise ScenarioError(shown, "", "expected a mapping of sections at the top level")
    return text, data
