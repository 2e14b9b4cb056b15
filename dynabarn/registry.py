"""Named things of one kind, found one way: planners, planner presets, trackers, obstacle
behaviours, protocols, profile sets, shape mixes, static fields, tiers, world import
formats, recording topics, metrics, commands and ROS stacks are each a `Registry`
(docs/architecture.md's table, one row per kind, names where each lives).

A registry is a dict of what is built in and what was registered in this process
(`register`), plus what other packages install under its entry-point group, e.g.

    [project.entry-points."dynabarn.planners"]
    my_planner = "my_pkg.planner:MyPlanner"

Every registry is extended the same way, `register(item)`: the item carries its own name
(`item.name`; `name=` gives another), and the registry's `check` refuses what does not
keep its kind's contract, in one line, when it is registered and when it is installed.
`get(name)` looks in that order and fails with one line: an unknown name lists what is
available, an installed package that breaks on import is named.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib.metadata import EntryPoint, entry_points
from typing import Generic, TypeVar

from dynabarn.errors import DynabarnError, unknown_choice

T = TypeVar("T")
_WARNED: set[tuple[str, str]] = set()
"""Installed items already named in a warning in this process: (kind, name)."""


def instances_of(cls: type) -> Callable[[object], None]:
    """A registry's `check` for items that are instances of `cls` (protocols, profile sets)."""

    def check(item: object) -> None:
        if not isinstance(item, cls):
            raise TypeError(f"{item!r} is not a {cls.__module__}.{cls.__qualname__}")

    return check


def subclasses_of(cls: type) -> Callable[[object], None]:
    """A registry's `check` for items that are subclasses of `cls` (obstacle behaviours)."""

    def check(item: object) -> None:
        if not (isinstance(item, type) and issubclass(item, cls)):
            raise TypeError(f"{item!r} is not a subclass of {cls.__module__}.{cls.__qualname__}")

    return check


class Registry(dict[str, T], Generic[T]):
    """Built-in and registered items by name (the dict), and installed ones by entry point.

    Args:
        kind: what an item is, for messages ("planner", "profile set").
        items: the built-in items.
        group: the entry-point group other packages install items under (None: none).
        error: the error class of a failed lookup (a `DynabarnError`).
        check: the contract of an item (raises TypeError or ValueError with one line), applied
            to every item registered or installed; None: anything goes.
    """

    def __init__(
        self,
        kind: str,
        items: dict[str, T],
        *,
        group: str | None = None,
        error: type[DynabarnError] = DynabarnError,
        check: Callable[[T], None] | None = None,
    ) -> None:
        super().__init__(items)
        self.kind, self.group, self.error, self.check = kind, group, error, check
        self.builtin = frozenset(items)

    def register(self, item, legacy=None, *, name: str | None = None) -> T:
        """Make `item` available in this process under its own name (`item.name`) or `name`
        (other processes and machines: install it under the entry-point group), after the
        registry's check; returns it, so it also decorates a class. The older shape,
        `register(name, item)`, works for one more release, with a DeprecationWarning."""
        if legacy is not None and isinstance(item, str):
            import warnings

            warnings.warn(
                f"{self.kind} registration as register({item!r}, item) is the older shape: "
                f"use register(item, name={item!r}) (one way for every kind)",
                DeprecationWarning,
                stacklevel=3,
            )
            name, item = item, legacy
        if name is None:
            name = getattr(item, "name", None)
        if not isinstance(name, str) or not name:
            raise self.error(f"{self.kind} {item!r} has no name: give it a `name` or pass name=")
        self._checked(name, item)
        self[name] = item
        return item

    def _checked(self, name: str, item: T) -> T:
        if self.check is not None:
            try:
                self.check(item)
            except Exception as exc:  # TypeError or ValueError by contract; anything else is a broken item too
                raise self.error(f"{self.kind} {name!r}: {exc}") from None
        return item

    def installed(self) -> dict[str, EntryPoint]:
        """The items other packages offer under the entry-point group, not yet loaded."""
        return {ep.name: ep for ep in entry_points(group=self.group)} if self.group else {}

    def names(self) -> list[str]:
        """Every name `get` knows, sorted."""
        return sorted({*self, *self.installed()})

    def registered_at_run_time(self, name: str) -> bool:
        """`name` was registered in this process (`register`): worker processes that do not
        fork know only built-in and installed items."""
        return name in self and name not in self.builtin

    def get_item(self, name: str) -> T:
        """The item `name`: registered, built in, or installed (loaded now)."""
        if name in self:
            return self[name]
        ep = self.installed().get(name)
        if ep is None:
            raise self.error(unknown_choice(self.kind, name, self.names()))
        try:
            item = ep.load()
        except (Exception, SystemExit) as exc:  # a broken third-party package (one that exits on import too)
            why = f"it exited on import (SystemExit {exc.code!r})" if isinstance(exc, SystemExit) else str(exc)[:200]
            raise self.error(f"{self.kind} {name!r} failed to load from {ep.value}: {why}") from None
        return self._checked(name, item)

    def loaded(self) -> dict[str, T]:
        """Every item that can be used: built in, registered, and each installed one that
        loads and keeps the contract. One that does not is named in one warning on stderr
        (once per process) and left out, so that a broken package breaks only what asks for
        it by name (`get_item`: one line)."""
        items = dict(self)
        for name in sorted(set(self.installed()) - set(items)):
            try:
                items[name] = self.get_item(name)
            except self.error as exc:
                self.warn(name, exc)
        return items

    def installed_items(self) -> dict[str, T]:
        """The installed items that load and keep the contract (as `loaded`), by name, without
        those built in or registered in this process: read once per `sys.path` (scanning the
        installed packages costs ~2 ms), again only when the path changes."""
        import sys

        key = tuple(sys.path)
        if getattr(self, "_installed_key", None) != key:
            loaded = self.loaded()
            self._installed_items = {name: loaded[name] for name in sorted(loaded) if name not in self}
            self._installed_key = key
        return self._installed_items

    def run_time_items(self) -> tuple[T, ...]:
        """The items registered in this process (`register`), in the order registered."""
        return tuple(item for name, item in self.items() if name not in self.builtin)

    def warn(self, name: str, problem: Exception) -> None:
        """Say once per process that the installed item `name` is left out, and why."""
        import sys

        if (self.kind, name) not in _WARNED:
            _WARNED.add((self.kind, name))
            print(f"warning: {problem}; left out", file=sys.stderr)
