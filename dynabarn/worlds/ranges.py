"""The physical ranges of a world's numbers: a world file is untrusted data, so every
size, keyframe and count is checked where a `WorldSpec` is built (from a file or in code)."""

from __future__ import annotations

import math

import numpy as np

from dynabarn.errors import WorldError

MAX_OBSTACLES = 500
"""Moving obstacles per world (the paper's worlds have up to 15)."""
MAX_KEYFRAMES = 100_000
MAX_SCHEDULE_TIME = 1e5
"""Seconds a schedule may span before it loops."""
MAX_COORDINATE = 1000.0
"""Metres from the origin any position of a world may lie (the arena is 20 x 20 m)."""
MAX_OBSTACLE_SIZE = 20.0
MAX_STATIC_CYLINDERS = 10_000


def check_obstacle_numbers(obstacle) -> None:
    """Every number of an `Obstacle` in a physical range (a world file is untrusted data)."""
    for key in ("radius", "height", "half_length", "half_width"):
        value = getattr(obstacle, key)
        if not (isinstance(value, int | float) and math.isfinite(value) and 0 <= value <= MAX_OBSTACLE_SIZE):
            raise WorldError(f"obstacle {obstacle.name!r}: {key} {value!r} is not in [0, {MAX_OBSTACLE_SIZE:g}] m")
    if not math.isfinite(obstacle.yaw):
        raise WorldError(f"obstacle {obstacle.name!r}: yaw {obstacle.yaw!r} is not a finite angle")
    t, xy = obstacle.trajectory.times, obstacle.trajectory.xy
    if len(t) > MAX_KEYFRAMES:
        raise WorldError(f"obstacle {obstacle.name!r}: {len(t)} keyframes (at most {MAX_KEYFRAMES})")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(xy))):
        raise WorldError(f"obstacle {obstacle.name!r}: keyframes hold NaN or infinite values")
    if t[0] < 0 or np.any(np.diff(t) <= 0) or t[-1] > MAX_SCHEDULE_TIME:
        raise WorldError(
            f"obstacle {obstacle.name!r}: keyframe times must start at >= 0 s, rise strictly and end by "
            f"{MAX_SCHEDULE_TIME:g} s"
        )
    if np.abs(xy).max(initial=0.0) > MAX_COORDINATE:
        raise WorldError(f"obstacle {obstacle.name!r}: a keyframe lies more than {MAX_COORDINATE:g} m from the origin")


def check_layout(layout) -> None:
    """Every number of a `Layout` finite and in range."""

    def finite(values, limit: float) -> bool:
        return all(isinstance(v, int | float) and math.isfinite(v) and abs(v) <= limit for v in values)

    if not (finite(layout.goal, MAX_COORDINATE) and len(layout.goal) == 2):
        raise WorldError(f"layout: goal {layout.goal!r} must be two finite coordinates within {MAX_COORDINATE:g} m")
    if not (finite([layout.arena_half_size], MAX_COORDINATE) and layout.arena_half_size > 0):
        raise WorldError(f"layout: arena_half_size {layout.arena_half_size!r} must be in (0, {MAX_COORDINATE:g}] m")
    for w in layout.walls:
        if not (finite(w.centre, MAX_COORDINATE) and finite(w.size, MAX_COORDINATE) and min(w.size) > 0):
            raise WorldError(f"layout: wall {w.name!r} needs a finite centre and positive finite sizes")
    if len(layout.cylinders) > MAX_STATIC_CYLINDERS:
        raise WorldError(f"layout: {len(layout.cylinders)} static cylinders (at most {MAX_STATIC_CYLINDERS})")
    for c in layout.cylinders:
        if not (finite(c[:2], MAX_COORDINATE) and finite(c[2:], MAX_OBSTACLE_SIZE) and c[2] > 0):
            raise WorldError(f"layout: static cylinder {c!r} needs a finite position and a radius > 0")
