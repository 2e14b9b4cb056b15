"""The planner interface: what a planner sees (`Observation`) and what it returns.

A planner is any object with `reset(info)` and `act(obs) -> (v, w)`. It sees only
observations, never MuJoCo's data: the laser scan, its own pose and velocity, the goal,
the time, and (only when it declares `privileged = True`) the true obstacle states and
their schedules.
"""

from __future__ import annotations

import abc
from dataclasses import fields
from typing import ClassVar

from dynabarn.errors import EndEpisode
from dynabarn.sim.observation import EpisodeInfo, Observation, ObstacleState

__all__ = ["EndEpisode", "EpisodeInfo", "Observation", "ObstacleState", "Planner", "config_from_kwargs"]


def config_from_kwargs(cls, kwargs: dict, what: str):
    """Build the planner configuration dataclass `cls`, naming unknown keys and the known ones."""
    known = {f.name for f in fields(cls)}
    unknown = set(kwargs) - known
    if unknown:
        raise TypeError(f"unknown {what} parameter(s) {sorted(unknown)}; known: {sorted(known)}")
    return cls(**kwargs)


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
