"""Alg. 2: the 300 generated worlds.

Alg. 2 (paper Sec. III-B): obstacle_number ~ U{min, max}, then one Alg. 1 trajectory per
obstacle. The count range and the motion profiles come from the world's branch of the
difficulty tree (Fig. 2). Every world draws from its own `numpy.random.Generator` seeded
by `SeedSequence([base_seed, world_id])`: no global random state, and world 137 is the
same whether or not worlds 0-136 were generated first.

The 300 worlds: ids 0-99 easy (low count, easy motion), 100-149 medium (low count, hard
motion), 150-199 medium (high count, easy motion), 200-299 hard (high count, hard
motion). `paper60` takes 20 of each difficulty, 10 from each medium branch, like the
paper's baselines: ids 0-19, 100-109, 150-159, 200-219.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from dynabarn.errors import WorldError
from dynabarn.worlds.profiles import (
    CountClass,
    MotionClass,
    ProfileSet,
    ShapeMix,
    StaticField,
    difficulty_of,
)
from dynabarn.worlds.spec import SCRIPTED, SHAPE_NAMES, EndBehavior, Interpolation, Layout, Obstacle, WorldSpec
from dynabarn.worlds.static_field import generate_static_field
from dynabarn.worlds.trajectory import generate_trajectory

DEFAULT_BASE_SEED = 2022
N_WORLDS = 300


def branch_of(world_id: int) -> tuple[CountClass, MotionClass]:
    """The Fig. 2 branch of generated world `world_id` (0-299)."""
    if not 0 <= world_id < N_WORLDS:
        raise WorldError(f"world id {world_id} out of range 0-{N_WORLDS - 1}")
    if world_id < 100:
        return CountClass.LOW, MotionClass.EASY
    if world_id < 150:
        return CountClass.LOW, MotionClass.HARD
    if world_id < 200:
        return CountClass.HIGH, MotionClass.EASY
    return CountClass.HIGH, MotionClass.HARD


PAPER60: tuple[int, ...] = (*range(0, 20), *range(100, 110), *range(150, 160), *range(200, 220))
"""The fixed 60-world subset of the paper's baselines: 20 per difficulty."""


def world_rng(base_seed: int, world_id: int, stream: int = 0, draw: int = 0) -> np.random.Generator:
    """World `world_id`'s random stream: 0 its motions, 1 its shapes, 2 its static field.
    `draw` k > 0 is the k-th redraw of a world that was not certified solvable (the next
    seed of its own sequence: SeedSequence([seed, id, stream, k]))."""
    key = [base_seed, world_id] if stream == 0 else [base_seed, world_id, stream]
    if draw:
        key = [base_seed, world_id, stream, draw]
    return np.random.default_rng(np.random.SeedSequence(key))


def generate_world(
    world_id: int,
    profile_set: ProfileSet,
    *,
    base_seed: int = DEFAULT_BASE_SEED,
    interpolation: Interpolation = Interpolation.LINEAR,
    end_behavior: EndBehavior = EndBehavior.LOOP,
    shapes: ShapeMix | None = None,
    static_field: StaticField | None = None,
    behavior: str = SCRIPTED,
    behavior_params: Mapping[str, float] | None = None,
    draw: int = 0,
) -> WorldSpec:
    """Alg. 2 for world `world_id` of the 300: count, then one Alg. 1 trajectory each.

    Beyond the paper, `shapes` draws every obstacle's shape, `static_field` adds a
    BARN-style field of static cylinders and `behavior` with `behavior_params` makes every
    obstacle reactive (e.g. `yield` with `sim.behaviors.get_behavior("yield").defaults()`).
    Each draws from its own stream (SeedSequence([seed, id, 1]) and [seed, id, 2]), so the
    motions are the same as in the
    plain world of the same id and seed. `draw` > 0 redraws all of them (`world_rng`).
    """
    count_class, motion_class = branch_of(world_id)
    rng = world_rng(base_seed, world_id, 0, draw)
    lo, hi = profile_set.count_range(count_class)
    n_obstacles = int(rng.integers(lo, hi + 1))
    profiles = profile_set.motion_profiles(motion_class)
    trajectories = []
    for _ in range(n_obstacles):
        profile = profiles[int(rng.integers(len(profiles)))] if len(profiles) > 1 else profiles[0]
        trajectories.append(generate_trajectory(rng, profile, scheme=profile_set.waypoints))
    provenance: dict = {"generator": "dynabarn", "profiles": profile_set.to_dict()}
    if draw:
        provenance["draw"] = draw
    shape_kwargs: list[dict] = [{} for _ in trajectories]
    if shapes is not None and not shapes.cylinders_only:
        shape_rng = world_rng(base_seed, world_id, 1, draw)
        shape_kwargs = [draw_shape(shape_rng, shapes) for _ in trajectories]
        provenance["shapes"] = shapes.to_dict()
    layout = Layout()
    if static_field is not None:
        static_rng = world_rng(base_seed, world_id, 2, draw)
        layout = Layout(cylinders=generate_static_field(static_rng, static_field))
        provenance["static_field"] = static_field.to_dict()
    if behavior != SCRIPTED:
        provenance["behavior"] = behavior
    obstacles = tuple(
        Obstacle(
            name=f"obstacle_{k:03d}",
            trajectory=traj,
            behavior=behavior,
            behavior_params=dict(behavior_params or {}),
            **kw,
        )
        for k, (traj, kw) in enumerate(zip(trajectories, shape_kwargs, strict=True))
    )
    return WorldSpec(
        name=f"world_{world_id:03d}",
        world_id=world_id,
        difficulty=difficulty_of(count_class, motion_class),
        obstacles=obstacles,
        count_class=count_class,
        motion_class=motion_class,
        profile_set=profile_set.name,
        seed=base_seed,
        interpolation=interpolation,
        end_behavior=end_behavior,
        layout=layout,
        provenance=provenance,
    )


def draw_shape(rng: np.random.Generator, mix: ShapeMix) -> dict:
    """One obstacle's shape keyword arguments for `Obstacle`, drawn from `mix`."""
    w = np.asarray(mix.weights, dtype=np.float64)
    shape = SHAPE_NAMES[int(rng.choice(3, p=w / w.sum()))]
    yaw = round(float(rng.uniform(0.0, math.pi)), 6)
    if shape == "box":
        hl, hw = (round(float(v), 6) for v in rng.uniform(*mix.box_half_size, size=2))
        return {"shape": "box", "radius": 0.0, "half_length": hl, "half_width": hw, "yaw": yaw}
    if shape == "capsule":
        r = round(float(rng.uniform(*mix.capsule_radius)), 6)
        hl = round(float(rng.uniform(*mix.capsule_half_length)), 6)
        return {"shape": "capsule", "radius": r, "half_length": hl, "yaw": yaw}
    return {}
