"""Trackers by name (`TRACKERS`): what `TrackerConfig.kind` chooses. Built in: `kalman`
(`tracker.ObstacleTracker`: circles of the known radius) and `shaped`
(`shaped_tracker.ShapeTracker`: outlines of boxes, capsules and cylinders); another
package adds one under the entry-point group `dynabarn.trackers`: a class with
`for_episode(cfg, info)` whose instances have `update(time, scan, pose) -> Tracks` and
`detections` (what a planner reads of them)."""

from __future__ import annotations

from dynabarn.interfaces import EpisodeInfo
from dynabarn.perception.shaped_tracker import ShapeTracker
from dynabarn.perception.tracker import ObstacleTracker, TrackerConfig
from dynabarn.registry import Registry


def _check_tracker(item: object) -> None:
    for method in ("for_episode", "update"):
        if not callable(getattr(item, method, None)):
            raise TypeError(f"{item!r} has no {method}(): a tracker class has for_episode(cfg, info) and update(...)")


TRACKERS: Registry[type] = Registry(
    "tracker", {"kalman": ObstacleTracker, "shaped": ShapeTracker}, group="dynabarn.trackers", check=_check_tracker
)
"""Every tracker by name: built in, registered at run time (`TRACKERS.register(cls, name=...)`), installed."""


def make_tracker(cfg: TrackerConfig, info: EpisodeInfo):
    """The episode's tracker of the kind `cfg.kind` names, with `cfg` and the episode's map and laser."""
    return TRACKERS.get_item(cfg.kind).for_episode(cfg, info)
