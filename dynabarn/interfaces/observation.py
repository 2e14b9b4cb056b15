"""What a planner sees: `Observation` each tick, `EpisodeInfo` once, and for privileged
planners the true `ObstacleState`. Planners see these, never MuJoCo's data."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, slots=True)
class ObstacleState:
    """True obstacle state, for privileged planners only.

    Attributes:
        positions: (n_obstacles, 2) centres in the world frame [m].
        velocities: (n_obstacles, 2) [m/s].
        radii: (n_obstacles,) [m]: the radius of the circle around each footprint (a box's
            or capsule's bounding circle; a cylinder's own radius).
        predict: positions at future world time(s) [s]: (n_obstacles, 2) for one time,
            (T, n_obstacles, 2) for an array of T times. Exact for scripted obstacles (their
            schedules); in worlds with reactive obstacles, whose future depends on the
            robot, their present velocities extrapolated.
    """

    positions: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray
    predict: Callable[[float], np.ndarray]


@dataclass(frozen=True, slots=True)
class Observation:
    """What a planner sees at one control tick.

    Attributes:
        time: simulated time since the episode start [s].
        scan: (n_beams,) laser ranges [m], clipped to [range_min, range_max]; no return
            reads range_max.
        pose: (3,) robot x [m], y [m], yaw [rad] in the world frame.
        velocity: (2,) measured forward speed v [m/s] and yaw rate w [rad/s].
        goal_in_robot: (2,) goal position in the robot frame [m].
        goal_in_world: (2,) goal position in the world frame [m].
        obstacles: true obstacle state, or None for non-privileged planners.
    """

    time: float
    scan: np.ndarray
    pose: np.ndarray
    velocity: np.ndarray
    goal_in_robot: np.ndarray
    goal_in_world: np.ndarray
    obstacles: ObstacleState | None = None

    def __repr__(self) -> str:
        x, y, yaw = self.pose
        return f"Observation(t={self.time:.2f}s, pose=({x:.2f}, {y:.2f}, {yaw:.2f}), scan=({len(self.scan)},))"


@dataclass(frozen=True, slots=True)
class EpisodeInfo:
    """Fixed facts of an episode, given to `Planner.reset`.

    Attributes:
        laser_angles: (n_beams,) beam angles in the robot frame [rad].
        laser_offset: (2,) laser position in the robot frame [m].
        laser_range: (min, max) [m].
        control_period: time between `act` calls [s].
        v_limits: (min, max) forward speed [m/s]; w_max: yaw-rate bound [rad/s].
        accel_limits: (linear [m/s^2], angular [rad/s^2]) the runner enforces.
        footprint: (length, width) of the robot [m].
        walls: (n_walls, 4) static walls as (cx, cy, sx, sy) boxes [m]: the known map.
        goal: (2,) goal in the world frame [m]; goal_tolerance [m].
        seed: the episode's seed, for planners that randomise.
        static_obstacles: (n, 3) static cylinders (x, y, radius) [m]: also the known map.
        world_fingerprint: what makes the world the world it is (`worlds.fingerprint`),
            for a learned planner's check that it never trained on it ("" when unknown).
    """

    laser_angles: np.ndarray
    laser_offset: np.ndarray
    laser_range: tuple[float, float]
    control_period: float
    v_limits: tuple[float, float]
    w_max: float
    accel_limits: tuple[float, float]
    footprint: tuple[float, float]
    walls: np.ndarray
    goal: np.ndarray
    goal_tolerance: float
    seed: int = 0
    static_obstacles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    world_fingerprint: str = ""
    extra: dict = field(default_factory=dict)
