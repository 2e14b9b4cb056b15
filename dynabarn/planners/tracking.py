"""What every planner that tracks obstacles shares: its tracker's configuration (the
`tracker.*` keys, checked against the `Config` of the tracker they name), and each scan split into the tracked, moving
obstacles and what stands still (so a planner can leave the moving ones out of its static
picture), and how far beyond each track's outline a planner keeps clear
(`UncertaintyPadding`). A planner's tracker: `perception.trackers.make_tracker(cfg.tracker,
info)`, of the kind its configuration names (`tracker.kind`)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import partial
from typing import ClassVar

import numpy as np

from dynabarn.determinism import hypot
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


@dataclass
class UncertaintyPadding:
    """The settings of a planner that keeps clear of each track's predicted position grown by
    the tracker's uncertainty (`Tracks.padded_sizes`), a base of its configuration (`dwa`'s
    and `teb`'s with `include_dynamic_obstacles`, and `predictive`'s, which turns it on by
    default). Off by default, so every earlier result keeps its configuration."""

    uncertainty_sigmas: float = 0.0
    """Standard deviations of a prediction's position added to a track's radius (0: the
    radius alone, as every result before issue 57)."""
    max_padding: float = 0.3
    """Most that uncertainty adds to a track's radius [m]."""

    PADDING_LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "uncertainty_sigmas": (0.0, 10.0),
        "max_padding": (0.0, 5.0),
    }
    """The two settings' accepted ranges (a part of the configuration's `LIMITS`)."""
    RECORDED_WHEN_SET: ClassVar[dict[str, tuple[str, ...]]] = {
        "uncertainty_sigmas": ("uncertainty_sigmas", "max_padding")
    }
    """Recorded only when on: every earlier result's configuration stays as it was."""


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


def distance_to_tracks(
    x: np.ndarray, y: np.ndarray, t: np.ndarray, tracks: Tracks, padding: UncertaintyPadding
) -> np.ndarray:
    """Distance from each point (x, y), taken `t` seconds after the tracks' time, to the
    nearest track's surface then: every track at constant velocity, its radius grown by its
    uncertainty then (`padding`). x, y and t broadcast to one shape, which is the result's
    (inf without tracks). What `dwa` and `teb` keep clear of with `include_dynamic_obstacles`."""
    if not len(tracks):
        return np.full(np.broadcast_shapes(np.shape(x), np.shape(t)), np.inf)
    t = np.asarray(t)
    ox = tracks.positions[:, 0] + tracks.velocities[:, 0] * t[..., None]
    oy = tracks.positions[:, 1] + tracks.velocities[:, 1] * t[..., None]
    radii = tracks.padded_sizes(tracks.time + t, padding.uncertainty_sigmas, padding.max_padding)
    return (hypot(x[..., None] - ox, y[..., None] - oy) - radii).min(axis=-1)
