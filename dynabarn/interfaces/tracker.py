"""The tracker contract: what a laser tracker is asked (`for_episode`, `update`) and what a
planner may read of it (`obstacle_beams`), declared on one base class (`Tracker`).

A tracker turns each scan (and the robot's pose at it) into tracks of the moving obstacles
(`dynabarn.perception.Tracks`); the registry (`perception.trackers.TRACKERS`) holds
subclasses of `Tracker` only, and `dynabarn.check_tracker` checks one in behaviour.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import numpy as np

from dynabarn.interfaces.observation import EpisodeInfo

__all__ = ["Tracker"]


class Tracker(abc.ABC):
    """Base class of laser trackers. Subclasses implement `for_episode` and `update`."""

    name: ClassVar[str] = "tracker"

    @classmethod
    @abc.abstractmethod
    def for_episode(cls, cfg, info: EpisodeInfo) -> Tracker:
        """The episode's tracker, with its configuration (`perception.TrackerConfig`) and the
        episode's known map and laser (`info`); one per episode, remembering nothing of others."""

    @abc.abstractmethod
    def update(self, time: float, scan: np.ndarray, pose: np.ndarray):
        """Take one scan (n_beams,) and the robot's pose (x, y, yaw) at it; the tracks
        (`dynabarn.perception.Tracks`) at `time`."""

    def obstacle_beams(self, n_beams: int) -> np.ndarray:
        """(n_beams,) bool: the beams of the last scan that ended on an obstacle it detected,
        which a planner leaves out of its picture of what stands still. Default: none."""
        return np.zeros(n_beams, dtype=bool)
