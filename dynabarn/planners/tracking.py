"""What every planner that tracks obstacles shares: its tracker's configuration (the
`tracker.*` and `tracker.detector.*` keys), one tracker per episode, and which beams its
detections used (so a planner can leave the moving obstacles out of its static picture)."""

from __future__ import annotations

import numpy as np

from dynabarn.perception import DetectorConfig, ObstacleTracker, TrackerConfig
from dynabarn.planners.base import EpisodeInfo, config_from_kwargs, nested_config


def with_tracker(kwargs: dict, what: str) -> dict:
    """A planner's keyword configuration with its `tracker.*` (and `tracker.detector.*`)
    entries built into one checked `TrackerConfig` under "tracker"."""

    def build(sub: dict) -> TrackerConfig:
        sub = nested_config(
            sub, "detector", lambda d: config_from_kwargs(DetectorConfig, d, f"{what} tracker detector"), what
        )
        return config_from_kwargs(TrackerConfig, sub, f"{what} tracker")

    return nested_config(kwargs, "tracker", build, what)


def make_tracker(cfg: TrackerConfig, info: EpisodeInfo) -> ObstacleTracker:
    """An episode's tracker: its map and laser from `info`."""
    return ObstacleTracker.for_episode(cfg, info)


def tracked_beams(tracker: ObstacleTracker, n_beams: int) -> np.ndarray:
    """(n_beams,) True where the last scan's beam ended on a detected (moving) obstacle."""
    mask = np.zeros(n_beams, dtype=bool)
    det = tracker.detections
    if det is not None and len(det.beams):
        mask[det.beams[det.segment_of_point >= 0]] = True
    return mask
