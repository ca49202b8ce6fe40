"""A registry of names -> objects given as string entry points ("module:attribute").

Like gymnasium's ``register(entry_point="pkg.mod:Cls")`` and dm_control's ``TaggedTasks``:
registering imports nothing, an object is imported the first time it is asked for (and checked
then), a name can be registered once only, an unknown name raises :class:`UnknownNameError`
listing the valid ones, and each entry carries tags to select by. Installed packages add entries
through an entry-point group (:meth:`EntryPointRegistry.add_group`).

The pipeline registry (:mod:`exobench.benchmarks.registry`) and the track registry
(:mod:`exobench.benchmarks.tracks.registry`) are built on it.
"""

from __future__ import annotations

import importlib
import importlib.metadata
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from exobench.core.errors import ConfigError, UnknownNameError


def load_entry_point(entry_point: str) -> Any:
    """Import ``"module:attr.sub"`` and return the attribute."""
    module_name, sep, attr = entry_point.partition(":")
    if not sep or not module_name or not attr:
        raise ConfigError("entry_point", entry_point, "'module:attribute'")
    obj: Any = importlib.import_module(module_name)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


@dataclass(frozen=True)
class Entry:
    """One registry entry.

    Attributes:
        name: registry name, e.g. ``"rtls"`` or ``"stairs"``.
        entry_point: ``"module:attribute"`` of the registered object.
        tags: labels to select entries by without importing them (e.g. the track a pipeline serves).
        source: ``"builtin"``, ``"entry-point"`` or ``"user"`` (registered in code).
    """

    name: str
    entry_point: str
    tags: tuple[str, ...] = ()
    source: str = "builtin"


class EntryPointRegistry:
    """Objects by name; entries stay strings until first use.

    ``kind`` names the entries in error messages (``"pipeline"``, ``"track"``); ``check(name, obj)``
    validates an imported or directly registered object and returns it (raising ConfigError).
    """

    def __init__(self, kind: str, check: Callable[[str, Any], Any]) -> None:
        self.kind = kind
        self._check = check
        self._entries: dict[str, Entry] = {}
        self._loaded: dict[str, Any] = {}

    def register(self, name: str, entry_point: str | Any, *, tags: Iterable[str] = (), source: str = "user") -> None:
        """Add ``entry_point`` (a ``"module:attribute"`` string, or the object itself) under ``name``;
        refuse a name already taken."""
        if name in self._entries:
            taken = self._entries[name]
            raise ConfigError(
                f"{self.kind} name", name, f"a name not yet registered (taken by {taken.entry_point}, {taken.source})"
            )
        if not isinstance(entry_point, str):
            obj = self._check(name, entry_point)
            self._loaded[name] = obj
            entry_point = f"{obj.__module__}:{obj.__qualname__}"
        self._entries[name] = Entry(name, entry_point, tuple(tags), source)

    def add_group(self, group: str) -> None:
        """Register every entry point of an installed-package group (``[project.entry-points."<group>"]``)."""
        for ep in importlib.metadata.entry_points(group=group):
            self.register(ep.name, ep.value, source="entry-point")

    def names(self) -> list[str]:
        """Registered names in registration order (built-ins first)."""
        return list(self._entries)

    def entry(self, name: str) -> Entry:
        if name not in self._entries:
            raise UnknownNameError(self.kind, name, self._entries)
        return self._entries[name]

    def load(self, name: str) -> Any:
        """The registered object, imported and checked on first use."""
        entry = self.entry(name)
        if name not in self._loaded:
            try:
                obj = load_entry_point(entry.entry_point)
            except (ImportError, AttributeError) as e:
                raise ConfigError(f"{self.kind} {name!r}", entry.entry_point, f"an importable object ({e})") from None
            self._loaded[name] = self._check(name, obj)
        return self._loaded[name]

    def __contains__(self, name: object) -> bool:
        return name in self._entries
