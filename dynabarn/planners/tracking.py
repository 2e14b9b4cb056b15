"""What every planner that tracks obstacles shares: its tracker's configuration (the
`tracker.*` keys, checked against the `Config` of the tracker they name), and each scan split into the tracked, moving
obstacles and what stands still (so a planner can leave the moving ones out of its static
picture). A planner's tracker: `perception.trackers.make_tracker(cfg.tracker, info)`, of
the kind its configuration names (`tracker.kind`)."""

from __future__ import annotations

from dataclasses import fields
from functools import partial

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import (
    BaseTrackerConfig,
    CheckedConfig,
    Observation,
    Tracker,
    config_from_kwargs,
    nested_config,
)
from dynabarn.interfaces.tracker import DEFAULT_TRACKER
from dynabarn.perception import Tracks
from dynabarn.perception.trackers import TRACKERS


def with_tracker(kwargs: dict, what: str) -> dict:
    """A planner's keyword configuration with its `tracker.*` entries (and those of the
    tracker's nested settings, `tracker.detector.*`) built into one checked configuration
    under "tracker": the `Config` of the tracker `tracker.kind` names (`interfaces.Tracker`),
    so each tracker's settings are its own and one of another tracker is refused."""

    def build(sub: dict) -> BaseTrackerConfig:
        kind = sub.get("kind", DEFAULT_TRACKER)
        try:
            config_class = TRACKERS.get_item(kind).Config  # an unknown kind: one line, before anything runs
        except DynabarnError as exc:
            raise TypeError(str(exc)) from None
        for f in fields(config_class):  # nested settings (`detector`, `shape`): each checked too
            nested = f.default_factory
            if isinstance(nested, type) and issubclass(nested, CheckedConfig):
                sub = nested_config(
                    sub, f.name, partial(config_from_kwargs, nested, what=f"{what} tracker {f.name}"), what
                )
        return config_from_kwargs(config_class, sub, f"{what} tracker")

    return nested_config(kwargs, "tracker", build, what)


def track_moving(tracker: Tracker, obs: Observation, range_max: float) -> tuple[Tracks, np.ndarray, np.ndarray]:
    """Update `tracker` with the observation's scan; (the tracks, which beams ended on a
    detected obstacle (n_beams,), the scan with those beams reading no return): the moving
    obstacles are the tracker's, the rest of the scan is what stands still."""
    tracks = tracker.update(obs.time, obs.scan, obs.pose)
    moving = tracker.obstacle_beams(len(obs.scan))  # declared: interfaces.Tracker
    return tracks, moving, np.where(moving, range_max, obs.scan)
