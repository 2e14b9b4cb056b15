"""Crafted worlds with known answers."""

from __future__ import annotations

import textwrap
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


def slow_recorded_episode(path: Path, recorder: str, *, say: str) -> str:
    """A script that records a slow `stop`-like episode of world 0 to `path` with
    `recorder` (an expression of `dynabarn.recording`'s names, given `path`) and prints
    "running" at 1 s and `say` (an expression) at 40 s, for a test to kill it midway."""
    return textwrap.dedent(
        f"""
        import time
        from dynabarn.interfaces import Planner
        from dynabarn.protocol import get_protocol
        from dynabarn.recording import McapRecorder
        from dynabarn.recording.background import BackgroundRecorder
        from dynabarn.sim import run_episode
        from dynabarn.worldset import resolve_world

        class Slow(Planner):
            name = "slow"
            def act(self, obs):
                time.sleep(0.004)
                if obs.time == 1.0:
                    print("running", flush=True)
                if abs(obs.time - 40.0) < 1e-9:
                    print({say}, flush=True)
                return 0.0, 0.0

        path = {str(path)!r}
        recorder = {recorder}
        run_episode(resolve_world(0), Slow(), get_protocol("barn"), observers=[recorder])
        """
    )
