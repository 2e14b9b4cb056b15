"""Crafted worlds with known answers."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dynabarn.mjcf import write_world
from dynabarn.worlds.spec import EndBehavior, Interpolation, Obstacle, WorldSpec
from dynabarn.worlds.trajectory import Trajectory


def obstacle(name: str, keyframes) -> Obstacle:
    kf = np.asarray(keyframes, dtype=float)
    return Obstacle(name, Trajectory(times=kf[:, 0].copy(), xy=kf[:, 1:].copy(), profile="crafted"))


def crafted_world(path: Path, obstacles=(), *, name="crafted") -> Path:
    world = WorldSpec(
        name=name,
        world_id=None,
        difficulty="easy",
        obstacles=tuple(obstacles),
        profile_set="crafted",
        interpolation=Interpolation.LINEAR,
        end_behavior=EndBehavior.HOLD,
    )
    write_world(world, path)
    return path
