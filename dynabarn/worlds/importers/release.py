"""Import of the original DynaBARN release (Gazebo 9, 2022) into WorldSpecs.

The input is the reference JSON recovered from the release (`dynabarn60.json`): 600
obstacle plugins `{name: {difficulty, duration, keyframes: [[t, x, y], ...]}}` and 60
worlds `{id, obstacles, effective_obstacles, goal, walls, ...}`. Each world becomes a
WorldSpec that plays back like Gazebo did: spline interpolation, looping at `duration`,
and `effective_obstacles` (in five worlds two plugins share a class name and the second
cylinder most likely ran the first one's trajectory).

Difficulty of the release's worlds (by their position in the list, as in the paper's
baselines): 0-19 easy (low count, easy plugins), 20-29 medium (low count, medium+hard
plugins), 30-39 medium (high count, easy plugins), 40-59 hard (high count, medium+hard).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dynabarn.errors import ImportFormatError
from dynabarn.worlds.profiles import CountClass, MotionClass, difficulty_of
from dynabarn.worlds.spec import EndBehavior, Interpolation, Layout, Obstacle, WorldSpec
from dynabarn.worlds.trajectory import Trajectory

RELEASE_PROFILE_SET = "dynabarn-release"


def _branch(index: int) -> tuple[CountClass, MotionClass]:
    if index < 20:
        return CountClass.LOW, MotionClass.EASY
    if index < 30:
        return CountClass.LOW, MotionClass.HARD
    if index < 40:
        return CountClass.HIGH, MotionClass.EASY
    return CountClass.HIGH, MotionClass.HARD


def read_import_json(path: Path | str) -> object:
    """The JSON content of a file to import, or one clear ImportFormatError."""
    path = Path(path)
    if not path.is_file():
        raise ImportFormatError(f"import file not found: {path}")
    try:
        return json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ImportFormatError(f"{path}: not valid JSON ({exc})") from None


def load_release_json(path: Path | str) -> dict:
    data = read_import_json(path)
    if (
        not isinstance(data, dict)
        or not isinstance(data.get("plugins"), dict)
        or not isinstance(data.get("worlds"), list)
    ):
        raise ImportFormatError(f"{path}: not a dynabarn-release file (needs 'plugins' and 'worlds')")
    return data


def _trajectory(name: str, plugin: object) -> Trajectory:
    if not isinstance(plugin, dict) or "keyframes" not in plugin:
        raise ImportFormatError(f"plugin {name!r}: missing 'keyframes'")
    try:
        kf = np.asarray(plugin["keyframes"], dtype=np.float64)
    except (TypeError, ValueError):
        raise ImportFormatError(f"plugin {name!r}: keyframes are not numbers") from None
    if kf.ndim != 2 or kf.shape[1] != 3 or len(kf) < 2:
        raise ImportFormatError(f"plugin {name!r}: keyframes must be [[t, x, y], ...] with at least 2 rows")
    if not np.all(np.diff(kf[:, 0]) > 0):
        raise ImportFormatError(f"plugin {name!r}: keyframe times are not increasing")
    return Trajectory(
        times=np.ascontiguousarray(kf[:, 0]),
        xy=np.ascontiguousarray(kf[:, 1:]),
        profile=str(plugin.get("difficulty", "unknown")),
    )


def import_release(data: dict, *, use_effective: bool = True) -> list[WorldSpec]:
    """The release's worlds as WorldSpecs (spline, loop), in the file's order."""
    plugins = data["plugins"]
    worlds: list[WorldSpec] = []
    for index, w in enumerate(data["worlds"]):
        if not isinstance(w, dict):
            raise ImportFormatError(f"world #{index}: not an object")
        names = w.get("effective_obstacles" if use_effective else "obstacles") or w.get("obstacles")
        if not isinstance(names, list) or not names:
            raise ImportFormatError(f"world #{index}: no obstacle list")
        declared = w.get("obstacles", names)
        obstacles = []
        for k, plugin_name in enumerate(names):
            if plugin_name not in plugins:
                raise ImportFormatError(f"world #{index}: unknown plugin {plugin_name!r}")
            source = plugin_name if declared[k] == plugin_name else f"{declared[k]} (runs {plugin_name})"
            obstacles.append(
                Obstacle(
                    name=f"obstacle_{k:03d}", trajectory=_trajectory(plugin_name, plugins[plugin_name]), source=source
                )
            )
        count_class, motion_class = _branch(index)
        goal = w.get("goal", [-9.0, 0.0])
        world_id = int(w.get("id", index))
        worlds.append(
            WorldSpec(
                name=f"release_{world_id:03d}",
                world_id=world_id,
                difficulty=difficulty_of(count_class, motion_class),
                obstacles=tuple(obstacles),
                count_class=count_class,
                motion_class=motion_class,
                profile_set=RELEASE_PROFILE_SET,
                seed=None,
                interpolation=Interpolation.SPLINE,
                end_behavior=EndBehavior.LOOP,
                layout=Layout(goal=(float(goal[0]), float(goal[1]))),
                provenance={
                    "source": "DynaBARN release (Gazebo 9, 2022)",
                    "release_difficulty": str(w.get("difficulty", "")),
                    "plugins": list(declared),
                    "effective_plugins": list(names),
                    "recommended_protocol": "paper2022",
                },
            )
        )
    return worlds
