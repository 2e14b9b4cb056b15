"""Obstacle behaviours: how an obstacle answers the robot. One interface, one registry.

The paper's obstacles are `scripted`: they follow their schedules whatever the robot does.
Beyond the paper, an obstacle may be reactive. A world file names each obstacle's
behaviour and its parameters (`"behavior": "yield", "yield_distance": 1.5`); this module
turns them into motion. Every behaviour is an `ObstacleBehavior`: it declares its name and
parameters (with defaults, what the world generator writes) and, once per control
period, answers the robot for all its obstacles at once (numpy, no loop over obstacles)
with

- a schedule rate in [0, 1] per obstacle: 1 plays the schedule on, 0 holds it, between
  slows it (each reactive obstacle runs on its own clock);
- for behaviours that step off their paths (`moves_sideways`), a sideways speed along the
  path's left normal, held for the period; offsets stay within MAX_SIDEWAYS_OFFSET.

A new behaviour is one subclass here (or in your own package under the entry-point group
`dynabarn.behaviors`), registered by name; docs/architecture.md, "Extending", walks through one.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import ClassVar

import numpy as np

from dynabarn.determinism import OBSTACLE_SPEED_RESOLUTION, snap_array
from dynabarn.errors import WorldError
from dynabarn.registry import Registry, subclasses_of
from dynabarn.robot import JACKAL
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import SCRIPTED, Obstacle

ENTRY_POINT_GROUP = "dynabarn.behaviors"
MAX_SIDEWAYS_OFFSET = 3.0
"""[m] furthest any obstacle steps off its path."""


@dataclass(frozen=True, slots=True)
class Parameter:
    """One parameter of a behaviour, as a world file gives it."""

    default: float
    doc: str
    low: float = 0.0
    high: float = math.inf


@dataclass(frozen=True, slots=True)
class Surroundings:
    """The robot as every obstacle sees it at the start of a control period; arrays over
    all obstacles of the world (n)."""

    rel: np.ndarray
    """(n, 2) robot position minus the obstacle's centre [m]."""
    dist: np.ndarray
    """(n,) centre distance [m]."""
    velocity: np.ndarray
    """(n, 2) the obstacle's schedule velocity [m/s]."""
    normal: np.ndarray
    """(n, 2) left unit normal of its path (the last one while it stands)."""
    ahead: np.ndarray
    """(n,) the robot lies ahead, in its direction of travel."""
    side: np.ndarray
    """(n,) the robot's offset across the path [m] (+: on its left)."""
    reach: np.ndarray
    """(n,) centre distance at contact (bounding radius + the robot's) [m]."""
    lateral: np.ndarray
    """(n,) present sideways offset from the path [m] (+: left)."""
    lateral_speed: np.ndarray
    """(n,) present sideways speed [m/s]."""
    period: float
    """The control period [s]."""


class ObstacleBehavior(abc.ABC):
    """How obstacles of one behaviour answer the robot.

    Subclasses set `name`, `parameters` and implement `rates` (and `lateral_speeds` when
    `moves_sideways`). An instance serves all obstacles of its behaviour in one world:
    `members` marks them, `params[name]` holds each parameter per obstacle (n,).
    """

    name: ClassVar[str]
    parameters: ClassVar[Mapping[str, Parameter]] = MappingProxyType({})
    moves_sideways: ClassVar[bool] = False

    def __init__(self, members: np.ndarray, params: Mapping[str, np.ndarray]) -> None:
        self.members = members
        self.params = params

    @abc.abstractmethod
    def rates(self, s: Surroundings) -> np.ndarray:
        """Schedule rates (n,) in [0, 1] for this period; 1 for obstacles it leaves alone."""

    def lateral_speeds(self, s: Surroundings) -> np.ndarray:
        """Sideways speeds (n,) [m/s] of its members for this period (others: ignored)."""
        return np.zeros_like(s.lateral)

    @classmethod
    def summary(cls) -> str:
        """The docstring's first line, for `--help`."""
        lines = (cls.__doc__ or "").strip().splitlines()
        return lines[0].rstrip(".") if lines else cls.name

    @classmethod
    def defaults(cls) -> dict[str, float]:
        """The parameters a generated world writes for an obstacle of this behaviour."""
        return {k: p.default for k, p in cls.parameters.items()}


class Scripted(ObstacleBehavior):
    """The paper's obstacles: the schedule, whatever the robot does."""

    name = SCRIPTED

    def rates(self, s: Surroundings) -> np.ndarray:
        return np.ones_like(s.dist)


class Yield(ObstacleBehavior):
    """Holds still while the robot is ahead of it within `yield_distance`."""

    name = "yield"
    parameters: ClassVar[Mapping[str, Parameter]] = {"yield_distance": Parameter(1.5, "[m] centre to centre")}

    def rates(self, s: Surroundings) -> np.ndarray:
        return np.where(self.members & s.ahead & (s.dist < self.params["yield_distance"]), 0.0, 1.0)


class Avoid(ObstacleBehavior):
    """Steps around the robot within `avoid_distance`, then back onto its path.

    Social force (Helbing & Molnar 1995): within `avoid_distance` the robot pushes the
    obstacle sideways off its path with STRENGTH * exp((reach - d) / RANGE), weighted
    towards what lies ahead (ANISOTROPY), while a critically damped spring pulls it back
    onto the path; with the robot in its way within BRAKE_BAND it also slows its schedule.
    """

    name = "avoid"
    parameters: ClassVar[Mapping[str, Parameter]] = {
        "avoid_distance": Parameter(3.0, "[m] centre to centre: the robot is ignored beyond it")
    }
    moves_sideways = True

    STRENGTH = 4.0
    """[m/s^2] sideways push at contact distance (per unit mass)."""
    RANGE = 0.4
    """[m] decay length of the push."""
    ANISOTROPY = 0.35
    """Weight of a robot straight behind relative to one straight ahead (1)."""
    STIFFNESS = 0.5
    """[1/s^2] pull back onto the path ..."""
    DAMPING = 2 * math.sqrt(STIFFNESS)
    """[1/s] ... critically damped."""
    MAX_SPEED = 1.5
    """[m/s] fastest sideways step."""
    BRAKE_BAND = 1.0
    """[m] beyond contact distance, over which an obstacle with the robot in its way slows to a stop."""

    def _near(self, s: Surroundings) -> np.ndarray:
        return self.members & (s.dist < self.params["avoid_distance"])

    def rates(self, s: Surroundings) -> np.ndarray:
        in_way = self._near(s) & s.ahead & (np.abs(s.side) < s.reach)
        brake = np.clip((s.dist - s.reach) / self.BRAKE_BAND, 0.0, 1.0)
        return np.where(in_way, brake, 1.0)

    def lateral_speeds(self, s: Surroundings) -> np.ndarray:
        vel, dist = s.velocity, s.dist
        speed = np.hypot(vel[:, 0], vel[:, 1])
        along = (s.rel * vel).sum(axis=1) / np.where(speed > 1e-9, speed, 1.0)
        cos_phi = np.where(dist > 1e-9, along / np.maximum(dist, 1e-9), 1.0)
        weight = self.ANISOTROPY + (1 - self.ANISOTROPY) * (1 + cos_phi) / 2
        push = self.STRENGTH * np.exp((s.reach - dist) / self.RANGE) * weight
        away = np.where(s.side > 0, -1.0, 1.0)  # step away from the side the robot is on; dead ahead, step left
        force = np.where(self._near(s), away * push, 0.0)
        force -= self.STIFFNESS * s.lateral + self.DAMPING * s.lateral_speed  # back onto the path
        speed_lat = np.clip(s.lateral_speed + force * s.period, -self.MAX_SPEED, self.MAX_SPEED)
        return np.where(self.members, speed_lat, 0.0)


_BUILTIN: dict[str, type[ObstacleBehavior]] = {b.name: b for b in (Scripted, Yield, Avoid)}
BEHAVIORS: Registry[type[ObstacleBehavior]] = Registry(
    "obstacle behaviour", _BUILTIN, group=ENTRY_POINT_GROUP, error=WorldError, check=subclasses_of(ObstacleBehavior)
)
"""Every obstacle behaviour by name: built in, registered at run time, installed."""


def register_behavior(behavior: type[ObstacleBehavior]) -> type[ObstacleBehavior]:
    """Make a behaviour available by its name in this process (for worker processes and
    other machines, install it under the entry-point group `dynabarn.behaviors`)."""
    return BEHAVIORS.register(behavior)


def available_behaviors() -> list[str]:
    """Every behaviour that loads (a broken installed one is named in a warning, left out)."""
    return sorted(BEHAVIORS.loaded())


def get_behavior(name: str) -> type[ObstacleBehavior]:
    """The behaviour class registered under `name` (WorldError if none is)."""
    return BEHAVIORS.get_item(name)


def check_behaviors(obstacles: Sequence[Obstacle]) -> None:
    """Every obstacle's behaviour exists and its parameters are known and in range."""
    for o in obstacles:
        kind = get_behavior(o.behavior)
        for key, value in o.behavior_params.items():
            p = kind.parameters.get(key)
            if p is None:
                known = ", ".join(kind.parameters) or "none"
                raise WorldError(f"obstacle {o.name!r}: {o.behavior} has no parameter {key!r} (known: {known})")
            if not p.low <= value <= p.high:
                raise WorldError(f"obstacle {o.name!r}: {key} = {value} outside [{p.low:g}, {p.high:g}]")


class ReactiveObstacles:
    """The obstacles of a world with reactive ones, each on its own clock.

    Per control period: evaluate the schedules at the obstacles' clocks, let every
    behaviour answer the robot, advance the clocks by rate * period and the sideways
    offsets by their speeds, and return the period's positions for all physics steps.
    Everything actually played is kept in `log` for the clearance metric.
    """

    def __init__(
        self,
        obstacles: Sequence[Obstacle],
        player: SchedulePlayer,
        bounding_radii: np.ndarray,
        *,
        period: float,
        step_offsets: np.ndarray,
        max_steps: int,
    ) -> None:
        n = len(obstacles)
        self.player, self.period, self._offsets = player, period, step_offsets[:, None]
        self.behaviors: list[ObstacleBehavior] = []
        for name in dict.fromkeys(o.behavior for o in obstacles):  # first-seen order
            kind = get_behavior(name)
            members = np.array([o.behavior == name for o in obstacles])
            params = {
                key: np.array([o.behavior_params.get(key, p.default) for o in obstacles], dtype=np.float64)
                for key, p in kind.parameters.items()
            }
            self.behaviors.append(kind(members, params))
        self._sideways = [b for b in self.behaviors if b.moves_sideways]
        self.reach = bounding_radii + JACKAL.footprint_radius  # centre distance at contact
        self.clock = np.zeros(n)
        self.lateral = np.zeros(n)  # sideways offset from the path [m] ...
        self.lateral_speed = np.zeros(n)  # ... and its rate [m/s]
        self._normal = np.zeros((n, 2))  # last left normal of each path (kept when it stops)
        self.log = np.zeros((max_steps + 1, n, 2))

    def batch(self, robot_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """This period's positions and velocities (k, n, 2) of all obstacles."""
        pos, vel = self.player.positions_at_local(self.clock[None])
        pos, vel = pos[0], vel[0]
        normal = self._normal = self._step_normals(vel[None])[0]
        actual = pos + self.lateral[:, None] * normal
        rel = robot_xy - actual  # (n, 2) robot relative to each obstacle
        dist = np.hypot(rel[:, 0], rel[:, 1])
        ahead = (rel * vel).sum(axis=1) > 0.0
        side = (rel * normal).sum(axis=1)
        s = Surroundings(rel, dist, vel, normal, ahead, side, self.reach, self.lateral, self.lateral_speed, self.period)
        rate = np.ones(len(dist))
        for behavior in self.behaviors:
            rate = np.minimum(rate, behavior.rates(s))
        if self._sideways:
            speed = self.lateral_speed
            for behavior in self._sideways:
                speed = np.where(behavior.members, behavior.lateral_speeds(s), speed)
            # Never further than MAX_SIDEWAYS_OFFSET from the path; on a grid, so last-bit
            # differences of exp between machines stay out of the positions.
            limit = (MAX_SIDEWAYS_OFFSET - np.abs(self.lateral)) / self.period
            self.lateral_speed = snap_array(
                np.where(np.sign(speed) == np.sign(self.lateral), np.clip(speed, -limit, limit), speed),
                OBSTACLE_SPEED_RESOLUTION,
            )
        offsets = self._offsets
        local = self.clock[None, :] + offsets * rate[None, :]
        self.clock = self.clock + rate * self.period
        xy, v = self.player.positions_at_local(local)
        v = v * rate[None, :, None]
        if self._sideways:
            normals = self._step_normals(v)
            lateral = self.lateral[None, :] + offsets * self.lateral_speed[None, :]
            xy = xy + lateral[..., None] * normals
            v = v + self.lateral_speed[None, :, None] * normals
            self.lateral = self.lateral + self.lateral_speed * self.period
        return xy, v

    def _step_normals(self, v: np.ndarray) -> np.ndarray:
        """Left normals (k, n, 2) of the paths at the period's steps (last known when stopped)."""
        speed = np.hypot(v[..., 0], v[..., 1])[..., None]
        nrm = np.stack([-v[..., 1], v[..., 0]], axis=-1) / np.where(speed > 1e-9, speed, 1.0)
        return np.where(speed > 1e-9, nrm, self._normal[None])
