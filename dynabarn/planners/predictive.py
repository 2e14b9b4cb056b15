"""`predictive`: the oracle's time-aware search, fed by the laser tracker instead of the
schedules. Sensor-only: it reads the scan, its own pose and the clock, never `obs.obstacles`.

Per tick the tracker (`perception.tracker`) updates its tracks from the scan; every
rollout of the oracle's two-segment search (`oracle.py`) is checked against each track
extrapolated at constant velocity to the same future time. Predictions grow less certain
with time and are least certain for young tracks (a new track's speed is unknown until its
second detection), so the radius kept clear of grows with the prediction's standard
deviation: size + `uncertainty_sigmas` x std(t), at most `max_padding` beyond the size.
The known map (walls, static cylinders) is handled as by the oracle.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from dynabarn.interfaces import EpisodeInfo, Observation, config_from_kwargs
from dynabarn.perception import TrackerConfig, Tracks
from dynabarn.perception.trackers import make_tracker
from dynabarn.planners.oracle import OracleConfig, OraclePlanner
from dynabarn.planners.tracking import with_tracker


@dataclass
class PredictiveConfig(OracleConfig):
    uncertainty_sigmas: float = 1.0
    """Standard deviations of a prediction's position added to an obstacle's radius."""
    max_padding: float = 0.3
    """Most that uncertainty adds to an obstacle's radius [m]."""
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    """The tracker's parameters (`tracker.KEY=...`, `tracker.detector.KEY=...`)."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        **OracleConfig.LIMITS,
        "uncertainty_sigmas": (0.0, 10.0),
        "max_padding": (0.0, 5.0),
    }

    @classmethod
    def from_kwargs(cls, **kwargs) -> PredictiveConfig:
        return config_from_kwargs(cls, with_tracker(kwargs, "predictive"), "predictive")


class PredictivePlanner(OraclePlanner):
    """The oracle's search against the laser tracker's constant-velocity predictions."""

    name = "predictive"
    privileged = False
    config_class = PredictiveConfig

    def __init__(self, **config) -> None:
        super().__init__(**config)
        self._tracks = Tracks.empty()

    def reset(self, info: EpisodeInfo) -> None:
        super().reset(info)
        self.tracker = make_tracker(self.cfg.tracker, info)
        self._tracks = Tracks.empty()

    def tracks(self) -> Tracks:
        return self._tracks

    def obstacle_future(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        self._tracks = self.tracker.update(obs.time, obs.scan, obs.pose)
        c = self.cfg
        tracks = self._tracks.covering_circles(c.tracker.shape.extent_sigmas)  # outlines as circles
        times = obs.time + self._steps
        padding = np.minimum(c.max_padding, c.uncertainty_sigmas * tracks.position_std(times))  # (K, n)
        return tracks.predict(times), tracks.sizes[None, :] + padding
