"""World importers, one registry (`IMPORTERS`): a format's name (`dynabarn-worlds import
--format NAME`), how its file is read and checked, and how its worlds are built. Built in:
the DynaBARN release's 60 worlds (`dynabarn-release`) and the 300 static BARN worlds
(`barn-static`); another package adds a format under the entry-point group
`dynabarn.importers` (a `WorldImporter`), found by the command and the golden set alike."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from dynabarn.errors import ImportFormatError
from dynabarn.registry import Registry, instances_of


@dataclass(frozen=True)
class WorldImporter:
    """One input format: `load(path)` reads and checks a file (one clear error otherwise);
    `build(data, name, declared)` makes its worlds, named after the set `name` (`declared`:
    the obstacles its world files declare rather than what ran, where the format has both)."""

    name: str
    description: str
    load: Callable[[Path], object]
    build: Callable[[object, str, bool], list]
    reference_file: str = ""
    """The file of this format in the reference data (`shared/reference/`), if any."""


def _release(data, name: str, declared: bool) -> list:
    from dynabarn.worlds.importers.release import import_release

    return import_release(data, name=name, use_effective=not declared)


def _release_file(path: Path):
    from dynabarn.worlds.importers.release import load_release_json

    return load_release_json(path)


def _barn(data, name: str, declared: bool) -> list:
    from dynabarn.worlds.importers.barn import import_barn_static

    return import_barn_static(data, name=name)


def _barn_file(path: Path):
    from dynabarn.worlds.importers.barn import load_barn_json

    return load_barn_json(path)


IMPORTERS: Registry[WorldImporter] = Registry(
    "world import format",
    {
        "dynabarn-release": WorldImporter(
            "dynabarn-release", "the DynaBARN release's 60 worlds", _release_file, _release, "dynabarn60.json"
        ),
        "barn-static": WorldImporter(
            "barn-static", "the 300 static BARN worlds", _barn_file, _barn, "barn300_static.json"
        ),
    },
    group="dynabarn.importers",
    error=ImportFormatError,
    check=instances_of(WorldImporter),
)
"""Every world import format by name: built in, registered at run time, installed."""


def import_worlds(fmt: str, path: Path, *, name: str, declared: bool = False) -> list:
    """The worlds of the file `path` in format `fmt`, named after the set `name`; a file
    that does not hold them is one `ImportFormatError` that names it."""
    importer = IMPORTERS.get_item(fmt)
    data = importer.load(Path(path))
    try:
        return importer.build(data, name, declared)
    except ImportFormatError as exc:
        raise ImportFormatError(f"{path}:\n  " + str(exc).replace("\n", "\n  ")) from None
