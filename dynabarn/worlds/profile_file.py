"""A generation profile from a file: motion profiles, counts and variants set by the user.

The paper's Alg. 1 takes the motion profiles (polynomial order, speed and speed-variation
ranges) from the user and Alg. 2 the obstacle-count ranges; "they can be changed based on
the user's preferences" (Sec. III-C). A profile file says all of it in TOML or JSON, one
table per motion profile of Fig. 2's two motion branches:

    name = "sprint"
    description = "hard obstacles up to the Jackal's 2 m/s and beyond"
    waypoints = "integer"          # or "release" (optional; default integer)
    low_count = [5, 9]             # Fig. 2's low branch (optional; default the paper's)
    high_count = [10, 19]          # its high branch

    [[easy_motion]]
    name = "easy"
    order = [1, 2]
    speed = [0.5, 1.0]
    std = [0.01, 0.1]

    [[hard_motion]]
    name = "sprint"
    order = [3, 4]
    speed = [2.0, 3.0]
    std = [0.1, 0.3]
    # speed_step = 0.1             # optional: speeds on a grid (the release's 0.1 m/s)
    # speed_limit = "redraw"       # optional: clip (the paper) or redraw out-of-range speeds

and optionally the variants beyond the paper: `shapes` (a shipped mix's name or a table of
`ShapeMix`'s fields), `static` (a shipped field's name or a table of `StaticField`'s
fields) and `behavior` (a name, or a table with `name` and `params`).

The file is untrusted input: it is read whole only up to `MAX_PROFILE_BYTES`, parsed, then
every key is checked against what it may be (an unknown key is a mistake, not an
extension), every number must be finite, and every range goes through the same checks as
`MotionProfile` and `ProfileSet`. Anything wrong is one `ProfileError` line naming the file
and the key.
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

from dynabarn.errors import ProfileError
from dynabarn.worlds.profiles import (
    HIGH_COUNT,
    LOW_COUNT,
    SHAPE_MIXES,
    STATIC_FIELDS,
    MotionProfile,
    ProfileSet,
    ShapeMix,
    StaticField,
    WaypointScheme,
)
from dynabarn.worlds.spec import SCRIPTED

MAX_PROFILE_BYTES = 1 << 20
"""A profile file is a few hundred bytes; anything over a megabyte is not one."""
MAX_PROFILES_PER_BRANCH = 16

_TOP = {
    "name",
    "description",
    "waypoints",
    "low_count",
    "high_count",
    "easy_motion",
    "hard_motion",
    "shapes",
    "static",
    "behavior",
}
_MOTION = {f.name for f in fields(MotionProfile)}
_BEHAVIOR = {"name", "params"}


@dataclass(frozen=True)
class GenerationProfile:
    """Everything `dynabarn-worlds generate` draws a set from, beyond the seed and playback."""

    profile_set: ProfileSet
    shapes: ShapeMix | None = None
    """None: the paper's cylinders."""
    static_field: StaticField | None = None
    behavior: str = SCRIPTED
    behavior_params: dict[str, float] = field(default_factory=dict)
    """Overrides of the behaviour's defaults (checked against them where the behaviours live)."""
    source: dict = field(default_factory=dict)
    """Where it came from ({"file": name, "sha256": ...}, or the base set and the options),
    recorded in the set's `index.json` as `profile_source`."""


def read_profile_file(path: Path | str) -> GenerationProfile:
    """Read, parse and check a TOML (`.toml`) or JSON (any other name) profile file."""
    data, source = load_profile_data(path)
    try:
        return profile_from_dict(data, default_name=Path(path).stem, source=source)
    except ProfileError as exc:
        raise ProfileError(f"{path}: {exc}") from None


def load_profile_data(path: Path | str) -> tuple[object, dict]:
    """A profile file parsed but not yet checked (what options may still change), and its
    source record: its name and the sha256 of its bytes."""
    path = Path(path)
    if not path.is_file():  # not a FIFO or a device, which could block or never end
        raise ProfileError(f"{path}: no such profile file (or not a regular file)")
    try:
        with path.open("rb") as f:
            data = f.read(MAX_PROFILE_BYTES + 1)
    except OSError as exc:
        raise ProfileError(f"{path}: cannot read the profile file ({exc.strerror or exc})") from None
    if len(data) > MAX_PROFILE_BYTES:
        raise ProfileError(f"{path}: over {MAX_PROFILE_BYTES} bytes: not a profile file")
    try:
        text = data.decode("utf-8")
        parsed = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except UnicodeDecodeError:
        raise ProfileError(f"{path}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{path}: not valid TOML ({exc})") from None
    except (json.JSONDecodeError, RecursionError) as exc:
        raise ProfileError(f"{path}: not valid JSON ({exc})") from None
    except ValueError as exc:  # an integer of thousands of digits (Python's conversion limit)
        raise ProfileError(f"{path}: a number too long to read ({str(exc)[:80]})") from None
    if not isinstance(parsed, dict):
        raise ProfileError(f"{path}: the profile must be a table (an object), not {type(parsed).__name__}")
    return parsed, {"file": path.name, "sha256": hashlib.sha256(data).hexdigest()}


def profile_from_dict(data: object, *, default_name: str, source: dict) -> GenerationProfile:
    """A checked `GenerationProfile` from parsed data (a file's, or built from options)."""
    table = _table(data, "the profile", _TOP)
    for branch in ("easy_motion", "hard_motion"):
        if branch not in table:
            raise ProfileError(f"{branch}: missing (one or more motion profiles of Fig. 2's {branch[:4]} branch)")
    profile_set = ProfileSet(
        name=_text(table.get("name", default_name), "name"),
        easy_motion=_motions(table["easy_motion"], "easy_motion"),
        hard_motion=_motions(table["hard_motion"], "hard_motion"),
        low_count=_pair(table.get("low_count", LOW_COUNT), "low_count", whole=True),
        high_count=_pair(table.get("high_count", HIGH_COUNT), "high_count", whole=True),
        waypoints=_choice(table.get("waypoints", "integer"), "waypoints", [s.value for s in WaypointScheme]),
        description=_text(table.get("description", ""), "description", empty=True),
    )
    behavior, params = _behavior(table.get("behavior", SCRIPTED))
    return GenerationProfile(
        profile_set=profile_set,
        shapes=_variant(table.get("shapes"), "shapes", SHAPE_MIXES, ShapeMix, none="cylinder"),
        static_field=_variant(table.get("static"), "static", STATIC_FIELDS, StaticField, none="none"),
        behavior=behavior,
        behavior_params=params,
        source=source,
    )


def _table(value: object, what: str, allowed: set[str]) -> dict:
    if not isinstance(value, dict):
        raise ProfileError(f"{what} must be a table (an object), not {type(value).__name__}")
    unknown = sorted(set(value) - allowed)
    if unknown:
        raise ProfileError(f"{what}: unknown key {unknown[0]!r} (allowed: {', '.join(sorted(allowed))})")
    return value


def _text(value: object, what: str, *, empty: bool = False) -> str:
    if not isinstance(value, str) or (not value and not empty) or len(value) > 200:
        raise ProfileError(f"{what} must be a string of at most 200 characters")
    return value


def _number(value: object, what: str, *, whole: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):  # a TOML date, a table, a string
        raise ProfileError(f"{what} must be a number, not {type(value).__name__} {str(value)[:40]!r}")
    if isinstance(value, int) and abs(value) > 10**6:  # before float(): 5,000 digits overflow it
        raise ProfileError(f"{what} must be finite and at most 1e6 in size, got {str(value)[:20]}...")
    if not math.isfinite(value) or abs(value) > 1e6:
        raise ProfileError(f"{what} must be finite and at most 1e6 in size, got {value}")
    if whole and value != int(value):
        raise ProfileError(f"{what} must be a whole number, got {value}")
    return int(value) if whole else float(value)


def _pair(value: object, what: str, *, whole: bool = False) -> tuple:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ProfileError(f"{what} must be a [min, max] pair")
    return tuple(_number(v, what, whole=whole) for v in value)


def _choice(value: object, what: str, choices: list[str]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise ProfileError(f"{what} must be one of {', '.join(choices)}, got {str(value)[:40]!r}")
    return str(value)


def _motions(value: object, branch: str) -> tuple[MotionProfile, ...]:
    if not isinstance(value, list) or not value or len(value) > MAX_PROFILES_PER_BRANCH:
        raise ProfileError(f"{branch} must be a list of 1 to {MAX_PROFILES_PER_BRANCH} motion profiles")
    profiles = []
    for k, item in enumerate(value):
        where = f"{branch}[{k}]"
        t = _table(item, where, _MOTION)
        missing = sorted({"order", "speed", "std"} - set(t))
        if missing:
            raise ProfileError(f"{where}: missing {missing[0]!r}")
        profiles.append(
            MotionProfile(
                name=_text(t.get("name", branch.split("_")[0]), f"{where}.name"),
                order=_pair(t["order"], f"{where}.order", whole=True),
                speed=_pair(t["speed"], f"{where}.speed"),
                std=_pair(t["std"], f"{where}.std"),
                speed_step=_number(t.get("speed_step", 0.0), f"{where}.speed_step"),
                speed_limit=_choice(t.get("speed_limit", "clip"), f"{where}.speed_limit", ["clip", "redraw"]),
            )
        )
    return tuple(profiles)


def _variant(value, what: str, registry, cls, *, none: str):
    """A shipped variant by name, or one made from a table of the dataclass's fields."""
    if value is None or value == none:
        return None
    if isinstance(value, str):
        if value not in registry.names():
            raise ProfileError(f"{what} must be {none}, one of {', '.join(registry.names())}, or a table")
        return registry.get_item(value)
    allowed = {f.name for f in fields(cls)}
    t = _table(value, what, allowed)
    kwargs: dict = {"name": _text(t.get("name", what), f"{what}.name")}
    for f in fields(cls):
        if f.name == "name" or f.name not in t:
            continue
        v = t[f.name]
        if isinstance(v, list):
            kwargs[f.name] = tuple(_number(x, f"{what}.{f.name}", whole=f.name == "smooth_iterations") for x in v)
        else:
            kwargs[f.name] = _number(v, f"{what}.{f.name}", whole=f.name == "smooth_iterations")
    if "weights" in kwargs and len(kwargs["weights"]) != 3:
        raise ProfileError(f"{what}.weights must be 3 numbers (cylinder, box, capsule)")
    for name in ("x_range", "y_range", "fill", "box_half_size", "capsule_radius", "capsule_half_length"):
        if name in kwargs and (not isinstance(kwargs[name], tuple) or len(kwargs[name]) != 2):
            raise ProfileError(f"{what}.{name} must be a [min, max] pair")
    return cls(**kwargs)


def _behavior(value: object) -> tuple[str, dict[str, float]]:
    if isinstance(value, str):
        return _text(value, "behavior"), {}
    t = _table(value, "behavior", _BEHAVIOR)
    name = _text(t.get("name", ""), "behavior.name")
    params = t.get("params", {})
    if not isinstance(params, dict) or len(params) > 32:
        raise ProfileError("behavior.params must be a table of at most 32 numbers")
    return name, {str(k): _number(v, f"behavior.params.{k}") for k, v in params.items()}
