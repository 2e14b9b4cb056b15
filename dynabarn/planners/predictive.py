"""`predictive`: the oracle's time-aware search, fed by the laser tracker instead of the
schedules. Sensor-only: it reads the scan, its own pose and the clock, never `obs.obstacles`.

Per tick the tracker (`perception.tracker`) updates its tracks from the scan; every
rollout of the oracle's two-segment search (`oracle.py`) is checked against each track
extrapolated at constant velocity to the same future time. Predictions grow less certain
with time and are least certain for young tracks (a new track's speed is unknown until its
second detection), so the radius kept clear of grows with the prediction's standard
deviation: size + `uncertainty_sigmas` x std(t), at most `max_padding` beyond the size.
The known map (walls, static cylinders) is handled as by the oracle.

With `scan_guard` > 0, the laser returns neither the map nor a track explains
(`perception.unexplained`: an obstacle the tracker lost, split or has not confirmed yet,
the corner of a box outside its circle) are planned against too, as standing points for
the first `scan_guard` seconds of every rollout: what a costmap's obstacle layer would
hold, where the tracks fall short.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from dynabarn.interfaces import EpisodeInfo, Observation, config_from_kwargs
from dynabarn.perception import TrackerConfig, Tracks
from dynabarn.perception.trackers import make_tracker
from dynabarn.perception.unexplained import UnexplainedReturns
from dynabarn.planners.oracle import OracleConfig, OraclePlanner
from dynabarn.planners.tracking import UncertaintyPadding, with_tracker

FAR_AWAY = 1e6
"""[m] Where a standing point is put for the rollout steps beyond `scan_guard`."""


@dataclass
class PredictiveConfig(UncertaintyPadding, OracleConfig):
    uncertainty_sigmas: float = 1.0
    """Standard deviations of a prediction's position added to an obstacle's radius: on by
    default, as `predictive` has always planned (and always recorded; `max_padding` is the
    shared one, `UncertaintyPadding`)."""
    scan_guard: float = 0.0
    """[s] How far ahead the returns no track or map explains are planned against, as
    standing points (0: not at all, as every result before issue 57)."""
    scan_guard_radius: float = 0.05
    """[m] The radius each such point is kept clear of."""
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    """The tracker's parameters (`tracker.KEY=...`, `tracker.detector.KEY=...`)."""

    # Every result before the guard keeps its configuration as recorded; the padding's two
    # keys are recorded always (not UncertaintyPadding's rule, which is for dwa and teb).
    RECORDED_WHEN_SET: ClassVar[dict[str, tuple[str, ...]]] = {"scan_guard": ("scan_guard", "scan_guard_radius")}
    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        **OracleConfig.LIMITS,
        **UncertaintyPadding.PADDING_LIMITS,
        "scan_guard": (0.0, 10.0),
        "scan_guard_radius": (0.0, 1.0),
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
        self._unexplained = UnexplainedReturns(info) if self.cfg.scan_guard > 0 else None
        # The rollout steps a standing point holds for; beyond them it is out of the way.
        self._guarded = self._steps <= self.cfg.scan_guard

    def tracks(self) -> Tracks:
        return self._tracks

    def updated_tracks(self, obs: Observation) -> Tracks:
        """The tracker's tracks after this tick's scan: what the search plans against (a
        diagnostic subclass may correct them, as `benchmarks/perception_gap.py` does)."""
        return self.tracker.update(obs.time, obs.scan, obs.pose)

    def obstacle_future(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        self._tracks = self.updated_tracks(obs)
        c = self.cfg
        tracks = self._tracks.covering_circles()  # outlines as circles
        times = obs.time + self._steps
        future, radii = tracks.predict(times), tracks.padded_sizes(times, c.uncertainty_sigmas, c.max_padding)
        if self._unexplained is None:
            return future, radii
        points = self._unexplained(obs, self._tracks)
        if not len(points):
            return future, radii
        held = np.where(self._guarded[:, None, None], points[None], FAR_AWAY)  # (K, m, 2)
        radius = np.broadcast_to(c.scan_guard_radius, (len(times), len(points)))
        return np.concatenate([future, held], axis=1), np.concatenate([radii, radius], axis=1)
