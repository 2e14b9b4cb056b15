"""Names a package hands on from its modules, imported when first asked for (PEP 562).

`dynabarn` and `dynabarn.sim` offer their main names at the top, but importing them must
not load everything those names need (MuJoCo, PyTorch): a planner that imports
`dynabarn.sim.behaviors` or reads `dynabarn.robot` loads no simulator. Each package gives
`lazy_exports` its table of homes and installs the two functions it returns.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping


def lazy_exports(package: str, homes: Mapping[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """`__getattr__` and `__dir__` for `package`: a name of `homes` (name -> module) is
    imported from its module on first use and kept in the package's namespace."""

    def get(name: str) -> object:
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(home), name)
        setattr(sys.modules[package], name, value)
        return value

    def names() -> list[str]:
        return sorted({*vars(sys.modules[package]), *homes})

    return get, names
