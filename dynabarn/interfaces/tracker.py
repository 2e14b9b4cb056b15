"""The tracker contract: what a laser tracker is asked (`for_episode`, `update`), what a
planner may read of it (`obstacle_beams`) and its own configuration (`Config`), declared on
one base class (`Tracker`).

A tracker turns each scan (and the robot's pose at it) into tracks of the moving obstacles
(`dynabarn.perception.Tracks`); the registry (`perception.trackers.TRACKERS`) holds
subclasses of `Tracker` only, and `dynabarn.check_tracker` checks one in behaviour.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dynabarn.interfaces.observation import EpisodeInfo
from dynabarn.interfaces.planner import CheckedConfig

__all__ = ["BaseTrackerConfig", "Tracker"]

DEFAULT_TRACKER = "kalman"
"""The tracker a planner uses when its configuration names none (`tracker.kind`)."""


@dataclass
class BaseTrackerConfig(CheckedConfig):
    """What every tracker's configuration starts with: `kind`, the registry name that
    chooses the tracker (`tracker.kind=shaped`). A tracker's own settings are the fields of
    its `Config`, a subclass; a planner's `tracker.*` keys are checked against the `Config`
    of the kind they name, so a setting of one tracker given to another is refused."""

    kind: str = DEFAULT_TRACKER
    RECORDED_WHEN_SET: ClassVar[dict[str, tuple[str, ...]]] = {"kind": ("kind",)}


class Tracker(abc.ABC):
    """Base class of laser trackers. Subclasses implement `for_episode` and `update`."""

    name: ClassVar[str] = "tracker"
    Config: ClassVar[type[BaseTrackerConfig]] = BaseTrackerConfig
    """The tracker's own configuration (a `BaseTrackerConfig` subclass): what `for_episode`
    is given, built from a planner's `tracker.*` keys and recorded with its configuration."""

    @classmethod
    @abc.abstractmethod
    def for_episode(cls, cfg, info: EpisodeInfo) -> Tracker:
        """The episode's tracker, with its configuration (an instance of `Config`) and the
        episode's known map and laser (`info`); one per episode, remembering nothing of others."""

    @abc.abstractmethod
    def update(self, time: float, scan: np.ndarray, pose: np.ndarray):
        """Take one scan (n_beams,) and the robot's pose (x, y, yaw) at it; the tracks
        (`dynabarn.perception.Tracks`) at `time`."""

    def obstacle_beams(self, n_beams: int) -> np.ndarray:
        """(n_beams,) bool: the beams of the last scan that ended on an obstacle it detected,
        which a planner leaves out of its picture of what stands still. Default: none."""
        return np.zeros(n_beams, dtype=bool)
