"""Named things of one kind, found one way: planners, obstacle behaviours, protocols,
profile sets, shape mixes and static fields are each a `Registry`.

A registry is a dict of what is built in and what was registered in this process
(`register`), plus what other packages install under its entry-point group, e.g.

    [project.entry-points."dynabarn.planners"]
    my_planner = "my_pkg.planner:MyPlanner"

`get(name)` looks in that order and fails with one line: an unknown name lists what is
available, an installed package that breaks on import is named.
"""

from __future__ import annotations

from importlib.metadata import EntryPoint, entry_points
from typing import Generic, TypeVar

from dynabarn.errors import DynabarnError, unknown_choice

T = TypeVar("T")


class Registry(dict[str, T], Generic[T]):
    """Built-in and registered items by name (the dict), and installed ones by entry point.

    Args:
        kind: what an item is, for messages ("planner", "profile set").
        items: the built-in items.
        group: the entry-point group other packages install items under (None: none).
        error: the error class of a failed lookup (a `DynabarnError`).
    """

    def __init__(
        self, kind: str, items: dict[str, T], *, group: str | None = None, error: type[DynabarnError] = DynabarnError
    ) -> None:
        super().__init__(items)
        self.kind, self.group, self.error = kind, group, error
        self.builtin = frozenset(items)

    def register(self, name: str, item: T) -> None:
        """Make `item` available as `name` in this process (other processes and machines:
        install it under the entry-point group)."""
        self[name] = item

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
            return ep.load()
        except Exception as exc:  # a broken third-party package: say which one
            raise self.error(f"{self.kind} {name!r} failed to load from {ep.value}: {exc}") from None
