"""Import of files in the original DynaBARN release's format (Gazebo 9, 2022) into WorldSpecs.

The input is a JSON file like the one recovered from the release (`dynabarn60.json`):
obstacle plugins `{name: {difficulty, duration, keyframes: [[t, x, y], ...]}}` and worlds
`{id, difficulty, obstacles, effective_obstacles, goal, ...}`. Each world becomes a
WorldSpec that plays back like Gazebo did: spline interpolation, looping at `duration`,
and `effective_obstacles` (in five of the release's worlds two plugins share a class name
and the second cylinder most likely ran the first one's trajectory).

Every label is read from the world's own data, never from its position in the file:
- motion class: the world's `difficulty` field (`easy`, or `hard+medium` for the release's
  mixed plugin folders), checked against its plugins (`easylibobs_*` easy,
  `mediumlibobs_*` / `hardlibobs_*` hard, and each plugin's own `difficulty`);
- count class: its number of obstacles, 5-9 low and 10-19 high as in the paper, and
  below-low / above-high for worlds outside both (later BARN Challenge sets have more);
- Fig. 2 difficulty from the two (`profiles.difficulty_of`).
Names carry the set's name (`--name`, default the file's name): `<set>_<id:03d>`.

A world is one of the paper's (provenance `paper_set: release60`, the only imported worlds
`dynabarn-bench` compares with the paper's Fig. 5) when the file says it comes from the
release's repository and commit, its id is one of the release's 60 and its classes are
the ones the release gives that id (0-19 easy, 20-39 medium, 40-59 hard).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from pathlib import Path

import numpy as np

from dynabarn.errors import ImportFormatError
from dynabarn.worlds.classes import CountClass, Difficulty, MotionClass, count_class_of, difficulty_of
from dynabarn.worlds.spec import EndBehavior, Interpolation, Layout, Obstacle, WorldSpec
from dynabarn.worlds.trajectory import Trajectory

RELEASE_PROFILE_SET = "dynabarn-release"
RELEASE_SOURCE = ("kevinhou912/ROS-Jackal-Data_Collection-Local", "5890c0c2b5e4dc0eb45a5f97c5efdd4a0ba88516")
"""Where the release was recovered from (the file's meta.source_repo and source_commit)."""
PLUGIN_NAME = re.compile(r"^(easy|medium|hard)libobs_\d+$")
MOTION_OF_LEVEL = {"easy": MotionClass.EASY, "medium": MotionClass.HARD, "hard": MotionClass.HARD}
"""A plugin's speed level -> Fig. 2's motion branch (the release's medium and hard plugins
share the hard branch's worlds)."""
MOTION_OF_FIELD = {"easy": MotionClass.EASY, "hard+medium": MotionClass.HARD, "medium+hard": MotionClass.HARD}
MOTION_OF_FIELD |= {"medium": MotionClass.HARD, "hard": MotionClass.HARD}
SET_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,40}$")
MAX_PROBLEMS = 40
"""Problems listed before the rest are counted."""


def release_difficulty_of_id(world_id: int) -> Difficulty:
    """The difficulty the release gives its world `world_id` (0-59)."""
    return (Difficulty.EASY, Difficulty.MEDIUM, Difficulty.HARD)[min(world_id // 20, 2)]


def read_import_json(path: Path | str) -> tuple[object, str]:
    """The JSON content of a file to import and the sha256 of its bytes, or one clear ImportFormatError."""
    path = Path(path)
    if not path.is_file():
        raise ImportFormatError(f"import file not found: {path}")
    data = path.read_bytes()
    try:
        return json.loads(data), hashlib.sha256(data).hexdigest()
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise ImportFormatError(f"{path}: not valid JSON ({type(exc).__name__}: {exc})") from None


def load_release_json(path: Path | str) -> dict:
    """The file's content with `_source` (file name, sha256) added, checked to have the format's shape."""
    data, sha256 = read_import_json(path)
    if (
        not isinstance(data, dict)
        or not isinstance(data.get("plugins"), dict)
        or not isinstance(data.get("worlds"), list)
    ):
        raise ImportFormatError(f"{path}: not a dynabarn-release file (needs 'plugins' and 'worlds')")
    return data | {"_source": {"file": Path(path).name, "sha256": sha256}}


def _plugin_level(name: str, plugin: dict, problems: list[str]) -> str | None:
    """A plugin's speed level (easy, medium, hard) from its name and its `difficulty`."""
    m = PLUGIN_NAME.match(name)
    by_name = m.group(1) if m else None
    field = plugin.get("difficulty")
    if field is not None and field not in MOTION_OF_LEVEL:
        problems.append(f"plugin {name!r}: difficulty {field!r} is not easy, medium or hard")
        return None
    if by_name and field and by_name != field:
        problems.append(f"plugin {name!r}: its name says {by_name} but its difficulty field says {field}")
        return None
    if not (by_name or field):
        problems.append(f"plugin {name!r}: no motion class (neither a <level>libobs_N name nor a difficulty)")
    return by_name or field


def _trajectory(name: str, plugin: object, problems: list[str]) -> Trajectory | None:
    if not isinstance(plugin, dict) or "keyframes" not in plugin:
        problems.append(f"plugin {name!r}: missing 'keyframes'")
        return None
    try:
        kf = np.asarray(plugin["keyframes"], dtype=np.float64)
    except (TypeError, ValueError):
        problems.append(f"plugin {name!r}: keyframes are not numbers")
        return None
    if kf.ndim != 2 or kf.shape[1] != 3 or len(kf) < 2:
        problems.append(f"plugin {name!r}: keyframes must be [[t, x, y], ...] with at least 2 rows")
        return None
    if not np.isfinite(kf).all():
        problems.append(f"plugin {name!r}: keyframes hold NaN or infinite values")
        return None
    if not np.all(np.diff(kf[:, 0]) > 0):
        k = int(np.argmin(np.diff(kf[:, 0]) > 0)) + 1
        problems.append(f"plugin {name!r}: keyframe times are not increasing (row {k}: {kf[k, 0]:g} s)")
        return None
    duration = plugin.get("duration")
    if duration is not None and not (isinstance(duration, int | float) and math.isfinite(duration)):
        problems.append(f"plugin {name!r}: duration {duration!r} is not a number")
    elif duration is not None and duration + 1e-9 < kf[-1, 0]:
        problems.append(f"plugin {name!r}: duration {duration:g} s ends before its last keyframe ({kf[-1, 0]:g} s)")
    m = PLUGIN_NAME.match(name)
    level = plugin.get("difficulty") or (m.group(1) if m else "unknown")
    return Trajectory(times=np.ascontiguousarray(kf[:, 0]), xy=np.ascontiguousarray(kf[:, 1:]), profile=str(level))


def _motion_class(where: str, w: dict, levels: list[str | None], problems: list[str]) -> MotionClass | None:
    """The world's motion class: its plugins', checked against its `difficulty` field."""
    classes = {MOTION_OF_LEVEL[lv] for lv in levels if lv in MOTION_OF_LEVEL}
    if len(classes) > 1:
        problems.append(f"{where}: mixes easy plugins with medium/hard ones (the release never does)")
        return None
    by_plugins = classes.pop() if classes else None
    field = w.get("difficulty")
    if field is None:
        return by_plugins
    if field not in MOTION_OF_FIELD:
        problems.append(f"{where}: difficulty {field!r} is not one of {', '.join(MOTION_OF_FIELD)}")
        return None
    if by_plugins is not None and MOTION_OF_FIELD[field] is not by_plugins:
        names = ", ".join(sorted({n for n in w.get("obstacles", []) if isinstance(n, str)})[:3])
        problems.append(f"{where}: difficulty {field!r} but its plugins ({names}, ...) are {by_plugins.value}-motion")
        return None
    return MOTION_OF_FIELD[field]


def _claims_release(data: dict) -> bool:
    meta = data.get("meta")
    return isinstance(meta, dict) and (meta.get("source_repo"), meta.get("source_commit")) == RELEASE_SOURCE


# Over 80 lines on purpose: one pass over the worlds that checks every field once and
# gathers every problem, so a bad file is reported whole rather than one error at a time.
def import_release(data: dict, *, name: str = "release", use_effective: bool = True) -> list[WorldSpec]:
    """The file's worlds as WorldSpecs (spline, loop), in the file's order; every problem
    of the file is one line of the ImportFormatError."""
    if not SET_NAME.match(name):
        raise ImportFormatError(f"set name {name!r}: use a letter, then letters, digits, _ or - (at most 41)")
    problems: list[str] = []
    plugins: dict = data["plugins"]
    trajectories, levels = {}, {}
    for plugin_name, plugin in plugins.items():
        trajectories[plugin_name] = _trajectory(plugin_name, plugin, problems)
        levels[plugin_name] = _plugin_level(plugin_name, plugin, problems) if isinstance(plugin, dict) else None
    source = data.get("_source", {})
    claims_release = _claims_release(data)
    worlds: list[WorldSpec] = []
    seen_ids: dict[int, int] = {}
    for index, w in enumerate(data["worlds"]):
        where = f"world #{index}"
        if not isinstance(w, dict):
            problems.append(f"{where}: not an object")
            continue
        world_id = w.get("id")
        if not isinstance(world_id, int) or isinstance(world_id, bool) or not 0 <= world_id <= 999_999:
            problems.append(f"{where}: id {world_id!r} is not a whole number in [0, 999999]")
            continue
        where = f"world #{index} (id {world_id})"
        if world_id in seen_ids:
            problems.append(f"{where}: the same id as world #{seen_ids[world_id]}")
        seen_ids.setdefault(world_id, index)
        declared = w.get("obstacles")
        if not isinstance(declared, list) or not declared or not all(isinstance(n, str) for n in declared):
            problems.append(f"{where}: 'obstacles' is not a non-empty list of plugin names")
            continue
        effective = w.get("effective_obstacles", declared) if use_effective else declared
        if not isinstance(effective, list) or len(effective) != len(declared):
            problems.append(f"{where}: 'effective_obstacles' does not pair with 'obstacles'")
            continue
        unknown = sorted({n for n in (*declared, *effective) if n not in plugins})
        if unknown:
            problems.append(f"{where}: unknown plugin(s) {', '.join(map(repr, unknown[:5]))}")
            continue
        twice = sorted({n for n in declared if declared.count(n) > 1})
        if twice:
            problems.append(f"{where}: plugin(s) {', '.join(map(repr, twice))} listed twice")
        n = len(declared)
        if "n_obstacles" in w and w["n_obstacles"] != n:
            problems.append(f"{where}: n_obstacles {w['n_obstacles']!r} but {n} obstacles are listed")
        goal = w.get("goal", [-9.0, 0.0])
        if not (
            isinstance(goal, list)
            and len(goal) == 2
            and all(isinstance(v, int | float) and math.isfinite(v) for v in goal)
        ):
            problems.append(f"{where}: goal {goal!r} is not [x, y]")
            continue
        motion_class = _motion_class(where, w, [levels.get(p) for p in declared], problems)
        if motion_class is None or any(trajectories.get(p) is None for p in effective):
            continue
        count_class = count_class_of(n)
        difficulty = difficulty_of(count_class, motion_class)
        paper = (
            claims_release
            and world_id < 60
            and count_class in (CountClass.LOW, CountClass.HIGH)
            and difficulty is release_difficulty_of_id(world_id)
        )
        obstacles = tuple(
            Obstacle(
                name=f"obstacle_{k:03d}",
                trajectory=trajectories[plugin_name],
                source=plugin_name if declared[k] == plugin_name else f"{declared[k]} (runs {plugin_name})",
            )
            for k, plugin_name in enumerate(effective)
        )
        worlds.append(
            WorldSpec(
                name=f"{name}_{world_id:03d}",
                world_id=world_id,
                difficulty=difficulty,
                obstacles=obstacles,
                count_class=count_class,
                motion_class=motion_class,
                profile_set=RELEASE_PROFILE_SET,
                seed=None,
                interpolation=Interpolation.SPLINE,
                end_behavior=EndBehavior.LOOP,
                layout=Layout(goal=(float(goal[0]), float(goal[1]))),
                provenance={
                    "source": "DynaBARN release (Gazebo 9, 2022)" if claims_release else "a dynabarn-release file",
                    "source_file": source.get("file"),
                    "source_sha256": source.get("sha256"),
                    "set": name,
                    "release_difficulty": w.get("difficulty"),
                    "plugins": list(declared),
                    "effective_plugins": list(effective),
                    "paper_set": "release60" if paper else None,
                    # The paper's pipeline spawned at (12, 0) in its own worlds; anything else, BARN's rules.
                    "recommended_protocol": "paper2022" if paper else "barn",
                },
            )
        )
    if problems:
        more = len(problems) - MAX_PROBLEMS
        lines = problems[:MAX_PROBLEMS] + ([f"... and {more} more problems"] if more > 0 else [])
        raise ImportFormatError("\n".join(lines))
    return worlds
