"""Obstacle detections from one laser scan: returns the map does not explain, cut into
segments, each fitted with a circle.

1. Every return (range below the maximum) becomes a world point through the robot's pose
   and the laser's mount; points within `map_margin` of the known map (walls, static
   cylinders) or outside the map's grid are the map's, not obstacles.
2. Consecutive remaining beams form a segment while each point is within `max_gap` of the
   last (a dropped beam between them also cuts).
3. Two obstacles side by side form one segment whose range rises to a maximum where their
   arcs meet; a segment is cut after every interior range maximum that stands more than
   `split_depth` above the lowest range on both of its sides (one convex arc has no such
   maximum).
4. Each segment with at least `min_points` points and at most `max_extent` metres from end
   to end is fitted with a circle of the known `radius` (Gauss-Newton on the distances to
   the points, started behind the segment's centroid as seen from the laser): a centre,
   the fit's RMS residual and the segment's half width (`size`, at least `radius`).

All of it is vectorised over beams and segments (sums by `np.bincount`), elementwise, so the
same scan gives the same bits on every CPU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dynabarn.determinism import sincos
from dynabarn.interfaces.observation import EpisodeInfo
from dynabarn.interfaces.planner import CheckedConfig
from dynabarn.perception.map_distance import BOUNDS, MapDistance


@dataclass
class DetectorConfig(CheckedConfig):
    radius: float = 0.5
    """Obstacle radius the circles are fitted with [m] (the paper's cylinders: 0.5)."""
    map_margin: float = 0.15
    """Returns this close to the known map are the map's [m]."""
    max_gap: float = 0.3
    """Consecutive returns farther apart than this start a new segment [m]."""
    split_depth: float = 0.04
    """A range maximum inside a segment this far above the lowest range on both of its
    sides splits the segment (two arcs meeting) [m]."""
    min_points: int = 3
    """Fewer returns than this are not a detection."""
    max_extent: float = 2.5
    """Segments longer than this from end to end are not an obstacle [m]."""
    fit_iterations: int = 5
    """Gauss-Newton iterations of the known-radius circle fit."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "radius": (0.01, 5.0),
        "map_margin": (0.0, 2.0),
        "max_gap": (0.01, 5.0),
        "split_depth": (0.001, 5.0),
        "min_points": (1, 720),
        "max_extent": (0.1, 20.0),
        "fit_iterations": (0, 50),
    }


@dataclass(frozen=True, slots=True)
class Detections:
    """What one scan shows of the obstacles, in the world frame.

    Attributes:
        centres: (m, 2) fitted circle centres [m].
        sizes: (m,) radius of a circle around the segment: the fitted radius, or half the
            segment's end-to-end length when longer [m].
        residuals: (m,) RMS distance of the segment's points from the fitted circle [m].
        n_points: (m,) returns in each segment.
        points: (k, 2) the returns not explained by the map [m] (segments' points, in scan order).
        beams: (k,) the beam index of each point.
        segment_of_point: (k,) the detection index of each point (-1: rejected segment).
    """

    centres: np.ndarray
    sizes: np.ndarray
    residuals: np.ndarray
    n_points: np.ndarray
    points: np.ndarray
    beams: np.ndarray
    segment_of_point: np.ndarray

    def __len__(self) -> int:
        return len(self.centres)


_BIG = 1e4
"""Offset per segment in the running minima (larger than any range)."""


class ObstacleDetector:
    """Scan -> `Detections`, for one episode's map and laser.

    Args:
        cfg: the detector's parameters.
        walls: (n, 4) the arena's walls (cx, cy, sx, sy) [m].
        static_obstacles: (m, 3) static cylinders (x, y, radius) [m].
        laser_angles: (beams,) beam angles in the robot frame [rad].
        laser_offset: (2,) the laser's position in the robot frame [m].
        range_max: the laser's maximum range (a beam with no return reads it) [m].
    """

    def __init__(
        self,
        cfg: DetectorConfig,
        *,
        walls: np.ndarray,
        static_obstacles: np.ndarray,
        laser_angles: np.ndarray,
        laser_offset: np.ndarray,
        range_max: float,
    ) -> None:
        self.cfg = cfg
        self.map = MapDistance(static_obstacles, walls, resolution=0.05)
        self.angles = np.asarray(laser_angles, dtype=np.float64)
        self.offset = np.asarray(laser_offset, dtype=np.float64)
        self.range_max = float(range_max)

    @classmethod
    def for_episode(cls, cfg: DetectorConfig, info: EpisodeInfo) -> ObstacleDetector:
        """The detector of an episode: its known map and laser from `info`."""
        return cls(
            cfg,
            walls=info.walls,
            static_obstacles=info.static_obstacles,
            laser_angles=info.laser_angles,
            laser_offset=info.laser_offset,
            range_max=info.laser_range[1],
        )

    def laser_origin(self, pose: np.ndarray) -> np.ndarray:
        """The laser's position in the world (2,) for a robot pose (x, y, yaw)."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        ox, oy = self.offset
        return np.array([pose[0] + c * ox - s * oy, pose[1] + s * ox + c * oy])

    def detect(self, scan: np.ndarray, pose: np.ndarray) -> Detections:
        cfg = self.cfg
        origin = self.laser_origin(pose)
        beam = np.flatnonzero(scan < self.range_max - 1e-6)
        r = scan[beam]
        sin_a, cos_a = sincos(self.angles[beam] + pose[2])
        pts = np.column_stack([origin[0] + r * cos_a, origin[1] + r * sin_a])
        x0, x1, y0, y1 = BOUNDS
        inside = (pts[:, 0] > x0) & (pts[:, 0] < x1) & (pts[:, 1] > y0) & (pts[:, 1] < y1)
        free = inside & (self.map.lookup(pts) >= cfg.map_margin)
        beam, r, pts = beam[free], r[free], pts[free]
        if len(beam) == 0:
            return _empty()
        # Segments: a cut before every point that is not the next beam or is too far away.
        step = np.hypot(*np.diff(pts, axis=0).T)
        cut = np.concatenate([[True], (np.diff(beam) > 1) | (step > cfg.max_gap)])
        cut |= self._arc_splits(r, np.cumsum(cut) - 1)
        seg = np.cumsum(cut) - 1
        n_seg = int(seg[-1]) + 1
        counts = np.bincount(seg, minlength=n_seg)
        first = np.flatnonzero(cut)
        last = np.concatenate([first[1:], [len(seg)]]) - 1
        extent = np.hypot(*(pts[last] - pts[first]).T)
        keep = (counts >= cfg.min_points) & (extent <= cfg.max_extent)
        centres, rms = self._fit(pts, seg, n_seg, counts, origin)
        index = np.full(n_seg, -1)
        index[keep] = np.arange(int(keep.sum()))
        return Detections(
            centres=centres[keep],
            sizes=np.maximum(cfg.radius, 0.5 * extent[keep]),
            residuals=rms[keep],
            n_points=counts[keep],
            points=pts,
            beams=beam,
            segment_of_point=index[seg],
        )

    def _arc_splits(self, r: np.ndarray, seg: np.ndarray) -> np.ndarray:
        """Cuts after interior range maxima standing `split_depth` above both sides' minima."""
        n = len(r)
        if n < 3:
            return np.zeros(n, dtype=bool)
        # Running minima within each segment, from the left and from the right: an offset of
        # _BIG per segment keeps every segment's minimum from leaking into the next.
        left = np.minimum.accumulate(r - seg * _BIG) + seg * _BIG
        right = np.minimum.accumulate((r + seg * _BIG)[::-1])[::-1] - seg * _BIG
        interior = np.zeros(n, dtype=bool)
        interior[1:-1] = (seg[1:-1] == seg[:-2]) & (seg[1:-1] == seg[2:])
        peak = np.zeros(n, dtype=bool)
        peak[1:-1] = (r[1:-1] > r[:-2]) & (r[1:-1] >= r[2:])
        deep = (r - left > self.cfg.split_depth) & (r - right > self.cfg.split_depth)
        after = np.zeros(n, dtype=bool)
        after[1:] = (interior & peak & deep)[:-1]
        return after

    def _fit(
        self, pts: np.ndarray, seg: np.ndarray, n_seg: int, counts: np.ndarray, origin: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Known-radius circle fits of every segment: centres (n_seg, 2), RMS residuals (n_seg,)."""
        radius = self.cfg.radius
        w = np.maximum(counts, 1)
        mean = np.column_stack([np.bincount(seg, pts[:, 0], n_seg), np.bincount(seg, pts[:, 1], n_seg)]) / w[:, None]
        away = mean - origin
        away /= np.maximum(np.sqrt(away[:, 0] ** 2 + away[:, 1] ** 2), 1e-9)[:, None]
        c = mean + radius * away  # the centre lies behind the visible arc
        damping = 1e-6 * w
        for _ in range(self.cfg.fit_iterations):
            dx, dy = pts[:, 0] - c[seg, 0], pts[:, 1] - c[seg, 1]
            d = np.maximum(np.sqrt(dx * dx + dy * dy), 1e-9)
            res = d - radius
            jx, jy = -dx / d, -dy / d  # d(distance)/d(centre)
            a11 = np.bincount(seg, jx * jx, n_seg) + damping
            a12 = np.bincount(seg, jx * jy, n_seg)
            a22 = np.bincount(seg, jy * jy, n_seg) + damping
            b1 = np.bincount(seg, jx * res, n_seg)
            b2 = np.bincount(seg, jy * res, n_seg)
            det = a11 * a22 - a12 * a12
            c[:, 0] -= (a22 * b1 - a12 * b2) / det
            c[:, 1] -= (a11 * b2 - a12 * b1) / det
        dx, dy = pts[:, 0] - c[seg, 0], pts[:, 1] - c[seg, 1]
        res = np.sqrt(dx * dx + dy * dy) - radius
        rms = np.sqrt(np.bincount(seg, res * res, n_seg) / w)
        return c, rms


def _empty() -> Detections:
    return Detections(
        centres=np.zeros((0, 2)),
        sizes=np.zeros(0),
        residuals=np.zeros(0),
        n_points=np.zeros(0, dtype=np.int64),
        points=np.zeros((0, 2)),
        beams=np.zeros(0, dtype=np.int64),
        segment_of_point=np.zeros(0, dtype=np.int64),
    )
