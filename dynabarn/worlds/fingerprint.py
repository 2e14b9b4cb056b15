"""A world's fingerprint: what makes it the same world, whatever its file or name says.

Two worlds with the same walls, goal, static cylinders and obstacles (shape, size and
schedule) are the same navigation problem, even when their names, ids, seeds, provenance,
obstacle order or file bytes differ. The fingerprint hashes exactly that, so a learned
policy's record of the worlds it trained on can be checked against any world it is asked
to drive in (`dynabarn.planners.learned.trained_on`).
"""

from __future__ import annotations

import hashlib

import numpy as np

from dynabarn.worlds.spec import WorldSpec

FINGERPRINT_CHARS = 16
"""Hex characters kept (64 bits: a collision among a million worlds has odds of 1 in 10^7)."""


def _hex(parts: list[bytes]) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(len(p).to_bytes(8, "little"))
        h.update(p)
    return h.hexdigest()


def world_fingerprint(world: WorldSpec) -> str:
    """The world's fingerprint (16 hex characters); obstacle order does not matter."""
    obstacles = []
    for o in world.obstacles:
        tr = o.trajectory
        # Keyframes are stored to 1 mm and 1 ms: rounding to those makes a world read back
        # from its MJCF (6 significant digits) hash like the one that was written.
        keys = np.round(np.column_stack([tr.times, tr.xy]).astype(np.float64), 3) + 0.0
        shape = np.round(np.array([o.radius, o.half_length, o.half_width, o.yaw], dtype=np.float64), 6) + 0.0
        head = f"{o.shape}|{o.behavior}|{sorted(o.behavior_params.items())}".encode()
        obstacles.append(_hex([head, shape.tobytes(), keys.tobytes()]))
    layout = world.layout
    walls = np.round(np.array([[*w.centre, *w.size] for w in layout.walls], dtype=np.float64), 6) + 0.0
    cylinders = np.round(np.array(layout.cylinders, dtype=np.float64).reshape(-1, 3), 6) + 0.0
    goal = np.round(np.array(layout.goal, dtype=np.float64), 6) + 0.0
    parts = [
        f"{world.interpolation.value}|{world.end_behavior.value}".encode(),
        walls.tobytes(),
        cylinders.tobytes(),
        goal.tobytes(),
        *(bytes.fromhex(h) for h in sorted(obstacles)),
    ]
    return _hex(parts)[:FINGERPRINT_CHARS]
