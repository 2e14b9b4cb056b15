"""Named planner configurations (`dwa@dwa_dynabarn_authors`, `--planner-config NAME`), a
`Registry` like every other kind: the files shipped in `presets/`, those registered in this
process (`PRESETS.register(Preset(name, path))`) and those other packages install under the
entry-point group `dynabarn.presets` (an entry point names a `Preset`).

A preset is a JSON object of a planner's parameters. Keys starting with "_" are notes and
left out ("_source": where the values come from, "_sources": one source per parameter),
except "_extends": the name of a preset whose parameters this one starts from (one place
for each published value).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.registry import Registry

PRESETS_DIR = Path(__file__).resolve().parent / "presets"
"""The planner configurations shipped with the package, one JSON file each."""


@dataclass(frozen=True)
class Preset:
    """A named planner configuration: its name and the JSON file that holds it."""

    name: str
    path: Path


def _check_preset(item: object) -> None:
    """A preset: a `Preset` whose file is a .json file that exists (read when it is used)."""
    if not isinstance(item, Preset):
        raise TypeError(f"{item!r} is not a dynabarn.planners.presets.Preset")
    path = Path(item.path)
    if path.suffix != ".json" or not path.is_file():
        raise ValueError(f"{path} is not a .json file")


PRESETS: Registry[Preset] = Registry(
    "planner preset",
    {p.stem: Preset(p.stem, p) for p in sorted(PRESETS_DIR.glob("*.json"))},
    group="dynabarn.presets",
    check=_check_preset,
)
"""Every named planner configuration: shipped, registered at run time, installed."""


def planner_presets() -> list[str]:
    """Names of the planner configurations, e.g. `dwa_barn_challenge`."""
    return PRESETS.names()


def read_planner_config(text: str, _seen: tuple[str, ...] = ()) -> dict:
    """A preset by name (`PRESETS`), or a planner configuration .json file: the parameters
    (the notes left out, `_extends` followed)."""
    path = Path(PRESETS.get_item(text).path) if text in planner_presets() else Path(text)
    if not path.is_file():
        raise DynabarnError(f"planner config file not found: {path}")
    try:
        cfg = json.loads(path.read_text())
    except (ValueError, RecursionError) as exc:  # JSON and UTF-8 errors, numbers of thousands of digits
        raise DynabarnError(f"{path}: planner config is not valid JSON ({exc})") from None
    if not isinstance(cfg, dict):
        raise DynabarnError(f"{path}: planner config must be a JSON object")
    base: dict = {}
    parent = cfg.get("_extends")
    if parent is not None:
        if not isinstance(parent, str) or parent not in planner_presets():
            raise DynabarnError(f"{path}: _extends must name a preset ({', '.join(planner_presets())})")
        if parent in _seen:
            raise DynabarnError(f"{path}: presets extend each other in a circle ({' -> '.join((*_seen, parent))})")
        base = read_planner_config(parent, (*_seen, parent))
    return base | {k: v for k, v in cfg.items() if not k.startswith("_")}
