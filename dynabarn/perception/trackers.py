"""Trackers by name (`TRACKERS`): what `tracker.kind` chooses. Built in: `kalman`
(`tracker.ObstacleTracker`: circles of the known radius) and `shaped`
(`shaped_tracker.ShapeTracker`: outlines of boxes, capsules and cylinders); another
package adds one under the entry-point group `dynabarn.trackers`: a subclass of
`dynabarn.interfaces.Tracker` (`for_episode(cfg, info)`, `update(time, scan, pose) ->
Tracks`, `obstacle_beams`, what a planner reads of it, and `Config`, its own settings)."""

from __future__ import annotations

from dataclasses import is_dataclass

from dynabarn.interfaces import BaseTrackerConfig, EpisodeInfo, Tracker
from dynabarn.perception.registered_tracker import RegisteredTracker
from dynabarn.perception.shaped_tracker import ShapeTracker
from dynabarn.perception.tracker import ObstacleTracker
from dynabarn.registry import Registry, subclasses_of

_is_tracker = subclasses_of(Tracker)


def _check_tracker(item: object) -> None:
    """A tracker: a `Tracker` subclass whose `Config` is a dataclass of `BaseTrackerConfig`."""
    _is_tracker(item)
    config = item.Config  # type: ignore[attr-defined]
    if not (isinstance(config, type) and issubclass(config, BaseTrackerConfig) and is_dataclass(config)):
        raise TypeError(f"{item!r}: its Config {config!r} is not a dataclass subclassing BaseTrackerConfig")


TRACKERS: Registry[type[Tracker]] = Registry(
    "tracker",
    {"kalman": ObstacleTracker, "shaped": ShapeTracker, "registered": RegisteredTracker},
    group="dynabarn.trackers",
    check=_check_tracker,
)
"""Every tracker by name: built in, registered at run time (`TRACKERS.register(cls)`), installed."""


def make_tracker(cfg: BaseTrackerConfig, info: EpisodeInfo):
    """The episode's tracker of the kind `cfg.kind` names, with `cfg` and the episode's map and laser."""
    return TRACKERS.get_item(cfg.kind).for_episode(cfg, info)
