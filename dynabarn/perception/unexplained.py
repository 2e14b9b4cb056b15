"""The laser returns nothing else explains (`UnexplainedReturns`): not the known map (the
scan reads as far as `MapScan` says the map is, or farther) and not a track (the point lies
outside every track's circle, grown by a margin).

A tracker that loses an obstacle, splits a box into pieces, or has not yet confirmed one
that just came into view leaves its returns unexplained; a planner that plans only against
tracks then drives into them. These points are what a costmap's obstacle layer keeps (the
ROS navigation stack's local costmap marks every return): here only the ones the tracks
miss, thinned to the nearest return in each group of beams, within a range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynabarn.determinism import sincos
from dynabarn.interfaces import EpisodeInfo, Observation
from dynabarn.perception.map_scan import MapScan
from dynabarn.perception.tracks import Tracks
from dynabarn.robot import mounted_pose


@dataclass(frozen=True)
class UnexplainedConfig:
    map_margin: float = 0.15
    """[m] A return this much shorter than the map's range is not the map's."""
    track_margin: float = 0.15
    """[m] A return this far beyond a track's circle is not the track's."""
    max_range: float = 4.0
    """[m] Returns farther than this are left out (nothing there needs avoiding yet)."""
    beams_per_point: int = 4
    """The nearest unexplained return of each group of this many beams is kept."""


class UnexplainedReturns:
    """Per tick, the world positions (m, 2) of the returns neither the map nor a track explains."""

    def __init__(self, info: EpisodeInfo, config: UnexplainedConfig | None = None) -> None:
        self.cfg = config or UnexplainedConfig()
        self.map_scan = MapScan(info)
        self.angles = np.asarray(info.laser_angles, dtype=np.float64)
        self.offset = np.asarray(info.laser_offset, dtype=np.float64)
        n, k = len(self.angles), self.cfg.beams_per_point
        self._groups = np.arange(n) // k
        self._nearest = np.empty(-(-n // k))

    def __call__(self, obs: Observation, tracks: Tracks) -> np.ndarray:
        c = self.cfg
        scan = obs.scan
        unexplained = (scan < self.map_scan(obs.pose) - c.map_margin) & (scan < c.max_range)
        beams = np.flatnonzero(unexplained)
        if len(beams) == 0:
            return np.zeros((0, 2))
        # The nearest return of each group of beams: the point avoidance needs.
        nearest = self._nearest
        nearest.fill(np.inf)
        np.minimum.at(nearest, self._groups[beams], scan[beams])
        keep = beams[scan[beams] == nearest[self._groups[beams]]]
        keep = keep[np.unique(self._groups[keep], return_index=True)[1]]  # one per group (equal ranges)
        ox, oy, yaw = mounted_pose(obs.pose, self.offset)
        s, co = sincos(self.angles[keep] + yaw)  # the same bits on every CPU
        points = np.stack([ox + scan[keep] * co, oy + scan[keep] * s], axis=1)
        if len(tracks):
            gap = np.hypot(
                points[:, None, 0] - tracks.positions[None, :, 0], points[:, None, 1] - tracks.positions[None, :, 1]
            )
            points = points[(gap - tracks.sizes[None, :]).min(axis=1) > c.track_margin]
        return points
