"""Name -> plug-in registries (controllers, vehicle models) that refuse duplicates."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

from platoon_sumo.errors import did_you_mean

T = TypeVar("T")


class Registry(Generic[T]):
    """Maps a name used in scenario files to a class; `pkg.module:Class` loads a user's own."""

    def __init__(self, kind: str, check: Callable[[T], str | None] | None = None):
        """`check` returns why an object is not a valid plug-in of this kind (None: it
        is); it runs when a plug-in is registered and when one is loaded by its path."""
        self.kind = kind
        self.check = check
        self._entries: dict[str, T] = {}

    def register(self, name: str) -> Callable[[T], T]:
        def decorator(obj: T) -> T:
            if name in self._entries:
                raise ValueError(f"{self.kind} '{name}' is already registered")
            problem = self.check(obj) if self.check is not None else None
            if problem:
                raise TypeError(f"{self.kind} '{name}' {problem}")
            self._entries[name] = obj
            return obj

        return decorator

    def names(self) -> list[str]:
        return sorted(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def get(self, name: str) -> T:
        """The entry for `name`, or the object at dotted path `package.module:Attr`.

        Raises LookupError with a readable message (a suggestion, or the import failure).
        """
        if name in self._entries:
            return self._entries[name]
        if ":" in name:
            module_name, _, attr = name.partition(":")
            try:
                module = importlib.import_module(module_name)
            except Exception as exc:  # any failure while importing user code is reported
                raise LookupError(
                    f"cannot import plug-in module '{module_name}': {type(exc).__name__}: {exc}"
                ) from exc
            try:
                obj: T = getattr(module, attr)
            except AttributeError:
                raise LookupError(f"module '{module_name}' has no attribute '{attr}'") from None
            problem = self.check(obj) if self.check is not None else None
            if problem:
                raise LookupError(f"'{name}' is not a {self.kind}: it {problem}")
            return obj
        hint = did_you_mean(name, self._entries)
        known = ", ".join(self.names())
        suffix = f"; {hint}" if hint else ""
        raise LookupError(
            f"unknown {self.kind} '{name}' "
            f"(known: {known}, or a 'package.module:Class' path{suffix})"
        )
