"""A multi-obstacle tracker on the laser alone: detect, associate, filter, manage tracks.

Per scan (`ObstacleTracker.update`):

1. predict every track to the scan's time with a constant-velocity model (white-noise
   acceleration of standard deviation `accel_std`);
2. detect obstacles in the scan (`detect.py`: returns the map does not explain, segments,
   known-radius circle fits);
3. associate detections with tracks by the Hungarian method
   (`scipy.optimize.linear_sum_assignment`) on centre distances, gated at `gate` metres
   plus three standard deviations of the track's predicted position;
4. update matched tracks with a Kalman filter per axis (position measured, measurement
   standard deviation `measurement_std` times sqrt(8 / points), at least 1 mm);
5. unmatched detections start tracks at rest with speed uncertainty `birth_speed_std`;
6. an unmatched track coasts: it is dropped after `max_coast` seconds unseen, or after
   `max_unseen_in_view` seconds when the laser saw through where it should be (in view,
   in range, and the beam at its bearing returned beyond it: it is not there), so an
   obstacle hidden behind another keeps its identity while one that vanished does not
   linger.

Everything is vectorised over tracks and detections and uses elementwise arithmetic only
(no BLAS), and the state is kept on `STATE_RESOLUTION`'s grid, so the same scans give the
same tracks on every CPU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from scipy.optimize import linear_sum_assignment

from dynabarn.determinism import STATE_RESOLUTION, snap_array
from dynabarn.interfaces.observation import EpisodeInfo
from dynabarn.interfaces.tracker import BaseTrackerConfig, Tracker
from dynabarn.perception.detect import Detections, DetectorConfig, ObstacleDetector
from dynabarn.perception.tracks import Tracks

NO_MATCH = 1e6
"""Association cost of a pair beyond the gate."""


@dataclass
class TrackerConfig(BaseTrackerConfig):
    """The `kalman` tracker's configuration (`ObstacleTracker`), after `kind` (which tracker:
    `kalman`, this module's circles of the known radius; `shaped`, `shaped_tracker`'s
    outlines, whose `ShapeTrackerConfig` adds `shape`; or one registered or installed under
    `dynabarn.trackers`; recorded with a planner's configuration only where it is not
    `kalman`)."""

    accel_std: float = 2.0
    """White-noise acceleration of the motion model [m/s^2] (the paper's obstacles change
    speed and turn along polynomial paths)."""
    measurement_std: float = 0.02
    """Standard deviation of a detected centre with 8 returns [m] (fewer returns: more)."""
    birth_speed_std: float = 2.0
    """Speed uncertainty of a new track [m/s]: its second detection sets its velocity."""
    gate: float = 0.6
    """Association gate beyond three standard deviations of the predicted position [m]."""
    max_coast: float = 1.0
    """Seconds a track is kept without a detection (hidden behind another obstacle or out of view)."""
    max_unseen_in_view: float = 0.3
    """Seconds a track is kept while the laser sees through its place."""
    detector: DetectorConfig = field(default_factory=DetectorConfig)

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "accel_std": (0.0, 100.0),
        "measurement_std": (1e-4, 5.0),
        "birth_speed_std": (0.0, 20.0),
        "gate": (0.0, 10.0),
        "max_coast": (0.0, 60.0),
        "max_unseen_in_view": (0.0, 60.0),
    }


class ObstacleTracker(Tracker):
    """Tracks moving obstacles from scans and odometry (world frame).

    Args:
        cfg: the tracker's parameters (its detector's parameters are `detector.cfg`).
        detector: the episode's detector (its known map and laser).
    """

    Config = TrackerConfig

    PER_TRACK: ClassVar[tuple[str, ...]] = (
        "ids", "x", "v", "p_xx", "p_xv", "p_vv", "size", "born", "seen", "unseen_in_view",
    )  # fmt: skip
    """The arrays with one entry per track (kept or dropped together)."""

    def __init__(self, cfg: TrackerConfig, detector: ObstacleDetector) -> None:
        self.cfg = cfg
        self.detector = detector
        self.angles = detector.angles
        self.range_max = detector.range_max
        self._next_id = 0
        self.time: float | None = None
        self.detections: Detections | None = None
        n = 0
        self.ids = np.zeros(n, dtype=np.int64)
        self.x = np.zeros((n, 2))  # position
        self.v = np.zeros((n, 2))  # velocity
        self.p_xx = np.zeros((n, 2))  # per-axis covariance: position, cross, velocity
        self.p_xv = np.zeros((n, 2))
        self.p_vv = np.zeros((n, 2))
        self.size = np.zeros(n)
        self.born = np.zeros(n)
        self.seen = np.zeros(n)
        self.unseen_in_view = np.zeros(n)

    name = "kalman"

    def obstacle_beams(self, n_beams: int) -> np.ndarray:
        """The beams of the last scan that ended in a detection (not a rejected segment)."""
        moving = np.zeros(n_beams, dtype=bool)
        det = self.detections
        if det is not None and len(det.beams):
            moving[det.beams[det.segment_of_point >= 0]] = True
        return moving

    @classmethod
    def for_episode(cls, cfg: TrackerConfig, info: EpisodeInfo) -> ObstacleTracker:
        """An episode's tracker: its known map and laser from `info`."""
        return cls(cfg, ObstacleDetector.for_episode(cfg.detector, info))

    def max_coast(self) -> float:
        """Seconds a track is kept without a detection."""
        return self.cfg.max_coast

    # -- the filter ---------------------------------------------------------------------------
    def _predict(self, dt: float) -> None:
        if dt <= 0.0 or not len(self.ids):
            return
        q = self.cfg.accel_std**2
        self.x += self.v * dt
        self.p_xx += 2.0 * dt * self.p_xv + dt * dt * self.p_vv + q * dt**3 / 3.0
        self.p_xv += dt * self.p_vv + q * dt * dt / 2.0
        self.p_vv += q * dt

    def _correct(self, k: np.ndarray, z: np.ndarray, r: np.ndarray) -> None:
        """Kalman update of tracks k with measured positions z (m, 2), variances r (m,) (the
        same on both axes) or (m, 2)."""
        self._update(k, z, r[:, None] if r.ndim == 1 else r, velocity=False)

    def _correct_velocity(self, k: np.ndarray, z: np.ndarray, r: np.ndarray) -> None:
        """Kalman update of tracks k with measured velocities z (m, 2) of variances r (m, 2)."""
        self._update(k, z, r, velocity=True)

    def _update(self, k: np.ndarray, z: np.ndarray, r: np.ndarray, *, velocity: bool) -> None:
        """The Kalman update of tracks k, per axis, by a measurement z (m, 2) of variance r
        (m, 2) of their velocity or their position: with the measured component's
        covariances with position and velocity (`with_x`, `with_v`), the gains are those
        over the innovation's variance, and each covariance loses its gain times them."""
        p_xx, p_xv, p_vv = self.p_xx[k], self.p_xv[k], self.p_vv[k]
        with_x, with_v = (p_xv, p_vv) if velocity else (p_xx, p_xv)
        s = (with_v if velocity else with_x) + r
        gain_x, gain_v = with_x / s, with_v / s
        innovation = z - (self.v[k] if velocity else self.x[k])
        self.x[k] += gain_x * innovation
        self.v[k] += gain_v * innovation
        self.p_xx[k] = p_xx - gain_x * with_x
        self.p_xv[k] = p_xv - gain_x * with_v
        self.p_vv[k] = p_vv - gain_v * with_v

    def _motion(
        self, k: np.ndarray, columns: np.ndarray, det: Detections, time: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Velocities measured for tracks k (matched with detections `columns`) other than by
        their centres: (the tracks, the velocities (m, 2), their variances (m, 2)), or None.
        This tracker measures centres only; `registered_tracker` registers returns."""
        return None

    def _remember(
        self, det: Detections, matched: np.ndarray, columns: np.ndarray, born: np.ndarray, time: float
    ) -> None:
        """What a tracker keeps of this scan beyond the filter's state (here nothing): after
        the scan, given the ids of the tracks `matched` with detections `columns` and the
        detections `born` as the last tracks."""

    # -- one scan -----------------------------------------------------------------------------
    def _next_scan(self, time: float, scan: np.ndarray, pose: np.ndarray) -> tuple[Detections, float, np.ndarray]:
        """Every track predicted to `time`, the scan's detections: (them, the time since the
        last scan, each one's measurement variance)."""
        dt = 0.0 if self.time is None else time - self.time
        self._predict(dt)
        self.time = time
        det = self.detector.detect(scan, pose)
        self.detections = det
        var = (self.cfg.measurement_std * np.sqrt(8.0 / np.maximum(det.n_points, 1))) ** 2 + 1e-6
        return det, dt, var

    def update(self, time: float, scan: np.ndarray, pose: np.ndarray) -> Tracks:
        """Take one scan (and the robot's pose at it); the tracks at `time`."""
        det, dt, var = self._next_scan(time, scan, pose)
        track_rows, det_cols = self._associate(det)
        if len(track_rows):
            motion = self._motion(track_rows, det_cols, det, time)  # from the predicted state
            self._correct(track_rows, det.centres[det_cols], var[det_cols])
            if motion is not None:
                self._correct_velocity(*motion)
            self.size[track_rows] = det.sizes[det_cols]
            self.seen[track_rows] = time
            self.unseen_in_view[track_rows] = 0.0
        matched_ids = self.ids[track_rows]  # rows move when stale tracks are dropped
        # The rows and columns left unmatched, in order (a mask: setdiff1d sorts, costing more).
        unmatched = np.ones(len(self.ids), dtype=bool)
        unmatched[track_rows] = False
        self._age_unmatched(np.flatnonzero(unmatched), scan, pose, dt)
        unclaimed = np.ones(len(det), dtype=bool)
        unclaimed[det_cols] = False
        born = np.flatnonzero(unclaimed)
        if len(born):
            self._birth(det.centres[born], det.sizes[born], var[born], time)
        self._remember(det, matched_ids, det_cols, born, time)
        # On a fixed grid: the state carried to the next scan is the same bits everywhere.
        snap_array(self.x, STATE_RESOLUTION, out=self.x)
        snap_array(self.v, STATE_RESOLUTION, out=self.v)
        return self.tracks()

    def _associate(self, det: Detections) -> tuple[np.ndarray, np.ndarray]:
        if not len(self.ids) or not len(det):
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        d = np.sqrt(((self.x[:, None, :] - det.centres[None, :, :]) ** 2).sum(axis=-1))
        gate = self.cfg.gate + 3.0 * np.sqrt(self.p_xx.max(axis=1))
        cost = np.where(d <= gate[:, None], d, NO_MATCH)
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] < NO_MATCH
        return rows[ok], cols[ok]

    def _age_unmatched(self, k: np.ndarray, scan: np.ndarray, pose: np.ndarray, dt: float) -> None:
        """Count the time unmatched tracks were in view and not there; drop the stale."""
        cfg = self.cfg
        if len(k):
            origin = self.detector.laser_origin(pose)
            rel = self.x[k] - origin
            dist = np.sqrt(rel[:, 0] ** 2 + rel[:, 1] ** 2)
            # libm's atan2, a few calls per scan: numpy's differs between CPUs in the last bits,
            # which could move a bearing across a beam boundary.
            bearing = np.array([math.atan2(y, x) for x, y in rel.tolist()]) - pose[2]
            bearing = (bearing + np.pi) % (2.0 * np.pi) - np.pi
            step = (self.angles[-1] - self.angles[0]) / (len(self.angles) - 1)
            beam = np.rint((bearing - self.angles[0]) / step).astype(np.int64)
            in_view = (beam >= 0) & (beam < len(self.angles)) & (dist < self.range_max)
            seen_through = np.zeros(len(k), dtype=bool)
            seen_through[in_view] = scan[beam[in_view]] > dist[in_view] + self.size[k][in_view]
            self.unseen_in_view[k] = np.where(seen_through, self.unseen_in_view[k] + dt, 0.0)
        stale = (self.time - self.seen > self.max_coast()) | (self.unseen_in_view > cfg.max_unseen_in_view)
        if stale.any():
            keep = ~stale
            for name in self.PER_TRACK:
                setattr(self, name, getattr(self, name)[keep])

    def _birth(self, centres: np.ndarray, sizes: np.ndarray, var: np.ndarray, time: float) -> None:
        n = len(centres)
        ids = np.arange(self._next_id, self._next_id + n, dtype=np.int64)
        self._next_id += n
        self.ids = np.concatenate([self.ids, ids])
        self.x = np.concatenate([self.x, centres])
        self.v = np.concatenate([self.v, np.zeros((n, 2))])
        self.p_xx = np.concatenate([self.p_xx, np.repeat(var[:, None], 2, axis=1)])
        self.p_xv = np.concatenate([self.p_xv, np.zeros((n, 2))])
        self.p_vv = np.concatenate([self.p_vv, np.full((n, 2), self.cfg.birth_speed_std**2)])
        self.size = np.concatenate([self.size, sizes])
        self.born = np.concatenate([self.born, np.full(n, time)])
        self.seen = np.concatenate([self.seen, np.full(n, time)])
        self.unseen_in_view = np.concatenate([self.unseen_in_view, np.zeros(n)])

    def tracks(self) -> Tracks:
        """The current tracks (copies)."""
        t = 0.0 if self.time is None else self.time
        return Tracks(
            time=t,
            ids=self.ids.copy(),
            positions=self.x.copy(),
            velocities=self.v.copy(),
            sizes=self.size.copy(),
            position_var=self.p_xx.copy(),
            velocity_var=self.p_vv.copy(),
            position_velocity_cov=self.p_xv.copy(),
            age=t - self.born,
            last_seen=self.seen.copy(),
        )
