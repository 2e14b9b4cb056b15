"""Reference planners with known behaviour: `straight` and `stop`."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import ClassVar

from dynabarn.interfaces import CheckedConfig, EpisodeInfo, Observation, Planner, config_from_kwargs


@dataclass
class StraightConfig(CheckedConfig):
    speed: float = 2.0
    """Cruise speed [m/s] (the Jackal's top speed)."""
    heading_gain: float = 2.0
    """Yaw-rate command per radian of heading error [1/s]."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {"speed": (0.0, 5.0), "heading_gain": (0.0, 100.0)}


class StraightPlanner(Planner):
    """Drive at the goal at full speed, turning towards it; no obstacle avoidance."""

    name = "straight"

    def __init__(self, **config: float) -> None:
        self.cfg = config_from_kwargs(StraightConfig, config, "straight")
        self._w_max = math.pi

    def reset(self, info: EpisodeInfo) -> None:
        self._w_max = info.w_max

    def act(self, obs: Observation) -> tuple[float, float]:
        gx, gy = obs.goal_in_robot
        heading = math.atan2(gy, gx)
        w = max(-self._w_max, min(self._w_max, self.cfg.heading_gain * heading))
        # Slow down while facing away from the goal, so turns stay tight.
        v = self.cfg.speed * max(0.0, math.cos(heading))
        return v, w

    def config(self) -> dict:
        return asdict(self.cfg)


class StopPlanner(Planner):
    """Never move (a timeout reference)."""

    name = "stop"

    def act(self, obs: Observation) -> tuple[float, float]:
        return 0.0, 0.0
