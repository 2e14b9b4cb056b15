"""What every planner that tracks obstacles shares: its tracker's configuration (the
`tracker.*` and `tracker.detector.*` keys), and each scan split into the tracked, moving
obstacles and what stands still (so a planner can leave the moving ones out of its static
picture). A planner's tracker: `perception.trackers.make_tracker(cfg.tracker, info)`, of
the kind its configuration names (`tracker.kind`)."""

from __future__ import annotations

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import Observation, Tracker, config_from_kwargs, nested_config
from dynabarn.perception import DetectorConfig, TrackerConfig, Tracks
from dynabarn.perception.shape_fit import ShapeConfig
from dynabarn.perception.trackers import TRACKERS


def with_tracker(kwargs: dict, what: str) -> dict:
    """A planner's keyword configuration with its `tracker.*` (and `tracker.detector.*`)
    entries built into one checked `TrackerConfig` under "tracker"."""

    def build(sub: dict) -> TrackerConfig:
        sub = nested_config(
            sub, "detector", lambda d: config_from_kwargs(DetectorConfig, d, f"{what} tracker detector"), what
        )
        sub = nested_config(sub, "shape", lambda d: config_from_kwargs(ShapeConfig, d, f"{what} tracker shape"), what)
        cfg = config_from_kwargs(TrackerConfig, sub, f"{what} tracker")
        try:
            TRACKERS.get_item(cfg.kind)  # an unknown kind: one line, before anything runs
        except DynabarnError as exc:
            raise TypeError(str(exc)) from None
        return cfg

    return nested_config(kwargs, "tracker", build, what)


def track_moving(tracker: Tracker, obs: Observation, range_max: float) -> tuple[Tracks, np.ndarray, np.ndarray]:
    """Update `tracker` with the observation's scan; (the tracks, which beams ended on a
    detected obstacle (n_beams,), the scan with those beams reading no return): the moving
    obstacles are the tracker's, the rest of the scan is what stands still."""
    tracks = tracker.update(obs.time, obs.scan, obs.pose)
    moving = tracker.obstacle_beams(len(obs.scan))  # declared: interfaces.Tracker
    return tracks, moving, np.where(moving, range_max, obs.scan)
