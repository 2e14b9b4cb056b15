"""Import of the 300 static BARN worlds (Perille et al. 2020) into WorldSpecs.

The reference format (`barn300_static.json`, recovered from the release): per world the
grid cells of its static cylinders (radius 0.075 m, 1 m tall), `cells[n] = [i, j]` at
x = -0.075 - 0.15 i, y = 0.075 + 0.15 j (columns i = 0 and 29 and row j = 0 are the
walls, rows 34-63 the 30 x 30 obstacle grid), the goal, and BARN's reference path
`path_rc` in grid cells (x = -4.425 + 0.15 r, y = 5.175 + 0.15 c). Every world becomes a
WorldSpec with no moving obstacle, its cylinders as static geoms, no box walls, and in
its provenance the reference path and its length: from the spawn of the `barn-static`
protocol along the path to the goal, the optimal length of the BARN score.

Difficulty: BARN's worlds are not labelled; we call ids 0-99 easy, 100-199 medium and
200-299 hard only to fit the benchmark's three-way tables.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dynabarn.errors import ImportFormatError
from dynabarn.worlds.importers.release import read_import_json
from dynabarn.worlds.profiles import Difficulty
from dynabarn.worlds.spec import EndBehavior, Interpolation, Layout, WorldSpec

CYLINDER_RADIUS = 0.075
CELL = 0.15
SPAWN = (-1.0, 1.0)
"""The launch file's spawn, used for the reference path's length (protocol `barn-static`)."""


def cell_xy(cells: np.ndarray) -> np.ndarray:
    """Cylinder centres (n, 2) [m] of grid cells (n, 2) [i, j]."""
    cells = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
    return np.column_stack([-0.075 - CELL * cells[:, 0], 0.075 + CELL * cells[:, 1]])


def path_xy(path_rc: np.ndarray) -> np.ndarray:
    rc = np.asarray(path_rc, dtype=np.float64).reshape(-1, 2)
    return np.column_stack([-4.425 + CELL * rc[:, 0], 5.175 + CELL * rc[:, 1]])


def load_barn_json(path: Path | str) -> dict:
    data, _ = read_import_json(path)
    if (
        not isinstance(data, dict)
        or not isinstance(data.get("worlds"), list)
        or not data["worlds"]
        or not all(isinstance(w, dict) and "cells" in w for w in data["worlds"])
    ):
        raise ImportFormatError(f"{path}: not a barn-static file (needs 'worlds' with 'cells')")
    return data


def import_barn_static(data: dict, *, name: str = "barn") -> list[WorldSpec]:
    """The static BARN worlds, named `<name>_<id>`."""
    from dynabarn.worlds.importers.release import SET_NAME

    if not SET_NAME.match(name):
        raise ImportFormatError(f"set name {name!r}: use a letter, then letters, digits, _ or - (at most 41)")
    worlds = []
    for index, w in enumerate(data["worlds"]):
        try:
            wid = int(w.get("id", index))
            xy = cell_xy(w["cells"])
            goal = tuple(float(v) for v in w.get("goal_link_xy", (-3.5, 13.0)))
            path = path_xy(w.get("path_rc", [])) if w.get("path_rc") else np.zeros((0, 2))
        except (TypeError, ValueError, KeyError) as exc:
            raise ImportFormatError(f"barn world #{index}: malformed ({exc})") from None
        pts = np.vstack([[SPAWN], path, [goal]]) if len(path) else np.array([SPAWN, goal])
        ref_len = float(np.hypot(*np.diff(pts, axis=0).T).sum())
        difficulty = Difficulty.EASY if wid < 100 else Difficulty.MEDIUM if wid < 200 else Difficulty.HARD
        worlds.append(
            WorldSpec(
                name=f"{name}_{wid:03d}",
                world_id=wid,
                difficulty=difficulty,
                obstacles=(),
                profile_set="barn-static",
                interpolation=Interpolation.LINEAR,
                end_behavior=EndBehavior.HOLD,
                layout=Layout(
                    walls=(),
                    goal=(goal[0], goal[1]),
                    arena_half_size=10.0,
                    cylinders=tuple((round(float(x), 6), round(float(y), 6), CYLINDER_RADIUS) for x, y in xy),
                ),
                provenance={
                    "source": "BARN static worlds (via the DynaBARN release)",
                    "reference_path": np.round(path, 6).tolist(),
                    "reference_path_length": round(ref_len, 6),
                    "barn_metrics": list(w.get("metrics", [])),
                    "recommended_protocol": "barn-static",
                },
            )
        )
    return worlds


def reference_length_check(world: WorldSpec) -> float:
    """Length of the stored reference path from the spawn to the goal (for tests)."""
    path = np.asarray(world.provenance["reference_path"]).reshape(-1, 2)
    pts = np.vstack([[SPAWN], path, [world.layout.goal]])
    return float(np.hypot(*np.diff(pts, axis=0).T).sum()) if len(pts) > 1 else math.inf
