"""Trackers by name (`TRACKERS`): what `TrackerConfig.kind` chooses. Built in: `kalman`
(`tracker.ObstacleTracker`: circles of the known radius) and `shaped`
(`shaped_tracker.ShapeTracker`: outlines of boxes, capsules and cylinders); another
package adds one under the entry-point group `dynabarn.trackers`: a subclass of
`dynabarn.interfaces.Tracker` (`for_episode(cfg, info)`, `update(time, scan, pose) ->
Tracks`, and `obstacle_beams`, what a planner reads of it)."""

from __future__ import annotations

from dynabarn.interfaces import EpisodeInfo, Tracker
from dynabarn.perception.shaped_tracker import ShapeTracker
from dynabarn.perception.tracker import ObstacleTracker, TrackerConfig
from dynabarn.registry import Registry, subclasses_of

TRACKERS: Registry[type[Tracker]] = Registry(
    "tracker",
    {"kalman": ObstacleTracker, "shaped": ShapeTracker},
    group="dynabarn.trackers",
    check=subclasses_of(Tracker),
)
"""Every tracker by name: built in, registered at run time (`TRACKERS.register(cls)`), installed."""


def make_tracker(cfg: TrackerConfig, info: EpisodeInfo):
    """The episode's tracker of the kind `cfg.kind` names, with `cfg` and the episode's map and laser."""
    return TRACKERS.get_item(cfg.kind).for_episode(cfg, info)
