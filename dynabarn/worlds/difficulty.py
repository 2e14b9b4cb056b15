"""A measured difficulty for a world, from its schedules alone (no simulation).

The paper sets difficulty by generation parameters (Fig. 2). This measures what a robot
would face on the straight corridor from spawn to goal: the band |y| <= half the Jackal's
width + the obstacle's (bounding) radius, from the goal (x = -9) to the spawn (x = 11), sampled every
0.1 s over 60 s of every obstacle's looping schedule.

- `corridor_blocked`: fraction of the time at least one obstacle is in the corridor;
- `corridor_occupancy`: mean number of obstacles in the corridor;
- `crossings_per_minute`: how often an obstacle enters the corridor.

Deterministic (pure numpy on the keyframes) and independent of any trial's clock offset:
60 s covers several loops of every schedule.
"""

from __future__ import annotations

import numpy as np

from dynabarn.robot import JACKAL
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import WorldSpec

WINDOW = 60.0
STEP = 0.1
CORRIDOR_X = (-9.0, 11.0)


def _corridor_half_widths(world: WorldSpec) -> np.ndarray:
    return JACKAL.width / 2 + np.array([o.bounding_radius for o in world.obstacles])  # a box's or capsule's circle


def _inside_corridor(xy: np.ndarray, half: np.ndarray) -> np.ndarray:
    return (np.abs(xy[..., 1]) <= half) & (xy[..., 0] >= CORRIDOR_X[0]) & (xy[..., 0] <= CORRIDOR_X[1])


def _sample(world: WorldSpec) -> tuple[np.ndarray, np.ndarray]:
    """Which obstacles are in the corridor (T, n) and their velocities (T, n, 2), every
    STEP over WINDOW seconds of the schedules."""
    xy, vel = SchedulePlayer(world).positions_at(np.arange(0.0, WINDOW, STEP))
    return _inside_corridor(xy, _corridor_half_widths(world)), vel


def _scores(inside: np.ndarray) -> dict[str, float]:
    entries = np.count_nonzero(inside[1:] & ~inside[:-1]) + np.count_nonzero(inside[0])
    return {
        "corridor_blocked": round(float(inside.any(axis=1).mean()), 6),
        "corridor_occupancy": round(float(inside.sum(axis=1).mean()), 6),
        "crossings_per_minute": round(float(entries * 60.0 / WINDOW), 6),
    }


def difficulty_scores(world: WorldSpec) -> dict[str, float]:
    if not world.obstacles:
        return {"corridor_blocked": 0.0, "corridor_occupancy": 0.0, "crossings_per_minute": 0.0}
    return _scores(_sample(world)[0])


def world_measures(world: WorldSpec) -> dict[str, float]:
    """`difficulty_scores` and, from the same sampling, the per-obstacle means that explain
    them: the fraction of time in the corridor, speed [m/s], loop duration [s], the span
    of the path in y [m] and how often the path crosses y = 0 per loop (none without
    moving obstacles)."""
    if not world.obstacles:
        return difficulty_scores(world)
    inside, vel = _sample(world)
    paths = [o.trajectory.xy for o in world.obstacles]
    return _scores(inside) | {
        "time_in_corridor": float(inside.mean()),
        "speed": float(np.hypot(vel[..., 0], vel[..., 1]).mean()),
        "loop_duration": float(np.mean([o.trajectory.duration for o in world.obstacles])),
        "y_span": float(np.mean([np.ptp(p[:, 1]) for p in paths])),
        "y_zero_crossings": float(np.mean([np.count_nonzero(np.diff(np.sign(p[:, 1]))) for p in paths])),
    }


NEAR_BAND = 2.0
"""[m] Half width of the band around the straight path whose obstacles `calibration_features`
counts as near it."""


def calibration_features(world: WorldSpec) -> dict[str, float]:
    """What a world's difficulty is predicted from (`bench.calibration`), from its schedules
    and static geometry alone: the obstacle count, `difficulty_scores`, the mean number of
    obstacles within NEAR_BAND of the straight path per 10 m of it (`near_density`), how fast
    those cut across it (`crossing_speed`, mean |v_y| [m/s]), and the share of the straight
    path within a robot's and a cylinder's radius of a static cylinder (`static_blocked`)."""
    features = {"n_obstacles": float(len(world.obstacles)), **difficulty_scores(world)}
    length = CORRIDOR_X[1] - CORRIDOR_X[0]
    if world.obstacles:
        xy, vel = SchedulePlayer(world).positions_at(np.arange(0.0, WINDOW, STEP))
        near = (np.abs(xy[..., 1]) <= NEAR_BAND) & (xy[..., 0] >= CORRIDOR_X[0]) & (xy[..., 0] <= CORRIDOR_X[1])
        features["near_density"] = float(near.sum(axis=1).mean() * 10.0 / length)
        features["crossing_speed"] = float(np.abs(vel[..., 1])[near].mean()) if near.any() else 0.0
    else:
        features["near_density"] = features["crossing_speed"] = 0.0
    cylinders = np.array(world.layout.cylinders, dtype=np.float64).reshape(-1, 3)
    blocked = 0.0
    if len(cylinders):
        xs = np.arange(CORRIDOR_X[0], CORRIDOR_X[1], STEP)
        gap = np.hypot(xs[:, None] - cylinders[None, :, 0], cylinders[None, :, 1]) - cylinders[None, :, 2]
        blocked = float((gap.min(axis=1) < JACKAL.width / 2).mean())
    features["static_blocked"] = blocked
    return features
