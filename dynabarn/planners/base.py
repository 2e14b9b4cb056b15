"""The planner interface: what a planner sees (`Observation`) and what it returns.

A planner is any object with `reset(info)` and `act(obs) -> (v, w)`. It sees only
observations, never MuJoCo's data: the laser scan, its own pose and velocity, the goal,
the time, and (only when it declares `privileged = True`) the true obstacle states and
their schedules.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import ClassVar

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
    extra: dict = field(default_factory=dict)


def config_from_kwargs(cls, kwargs: dict, what: str):
    """Build the planner configuration dataclass `cls`, naming unknown keys and the known ones."""
    known = {f.name for f in fields(cls)}
    unknown = set(kwargs) - known
    if unknown:
        raise TypeError(f"unknown {what} parameter(s) {sorted(unknown)}; known: {sorted(known)}")
    return cls(**kwargs)


class EndEpisode(Exception):
    """Raised by a planner to end its episode on purpose (outcome `error`, this reason)."""


class Planner(abc.ABC):
    """Base class of local planners. Subclasses set `name` and implement `act`."""

    name: ClassVar[str] = "planner"
    privileged: ClassVar[bool] = False
    """True if the planner needs the true obstacle states (`Observation.obstacles`)."""

    def reset(self, info: EpisodeInfo) -> None:  # noqa: B027 - optional hook
        """Called once before the first `act` of an episode."""

    @abc.abstractmethod
    def act(self, obs: Observation) -> tuple[float, float]:
        """Return the command (v [m/s], w [rad/s]) for this tick."""

    def debug(self) -> dict:
        """Optional planner internals to record (e.g. {'local_plan': (n, 2) array})."""
        return {}

    def config(self) -> dict:
        """The planner's parameters, recorded with every episode."""
        return {}

    def versions(self) -> dict[str, str]:
        """Versions of the libraries beyond the runner's that decide this planner's
        commands (e.g. PyTorch), recorded with every episode."""
        return {}
