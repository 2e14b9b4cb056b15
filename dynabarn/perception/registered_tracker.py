"""`registered`: the `kalman` tracker with each obstacle's velocity measured by registering
its returns onto those of the scan it was last seen in (`registration.py`), beside the
fitted centre.

What it changes, measured on validation worlds (issue 57): the fitted centre of a box or a
capsule (a circle of the known radius) moves as the laser's view of the outline turns, and
its differences were most of the velocity error; a rigid obstacle that never turns moves
its returns by one translation, whatever its shape. Each matched track gets two
measurements per scan, both per axis: its fitted centre (as `kalman`, its variance grown by
the fit's residual: a circle that does not fit says less of where the obstacle is) and the
registered translation over the time since its returns were kept, as a velocity. Along a
flat side seen without its ends the registration's variance is large and the filter keeps
its prediction there.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dynabarn.determinism import STATE_RESOLUTION, snap_array
from dynabarn.perception.detect import Detections
from dynabarn.perception.registration import padded, register
from dynabarn.perception.tracker import ObstacleTracker, TrackerConfig


@dataclass
class RegisteredTrackerConfig(TrackerConfig):
    """`registered`'s settings: `kalman`'s, and the registration's."""

    residual_weight: float = 3.0
    """A detection's fit residual times this is added to its centre's standard deviation."""
    registration_sigma: float = 0.03
    """Standard deviation of one matched return along its normal [m]: the laser's noise and
    the returns' spacing on the outline."""
    registration_trim: float = 0.15
    """Returns farther than this from their match are left out of a registration [m]."""
    registration_coarse_trim: float = 0.6
    """The trim of a registration's first step, halved at each step down to the trim [m]:
    an obstacle that turned since the last scan is off its predicted motion by up to twice
    its speed times the interval."""
    registration_prior: float = 0.01
    """Information added in every direction (in matched returns): along a direction no
    return constrains, the shift's variance is sigma^2 / prior."""
    registration_iterations: int = 5
    """Gauss-Newton steps of each registration."""
    min_matched: int = 4
    """Fewer matched returns than this: no velocity measurement."""
    min_matched_fraction: float = 0.5
    """Fewer of the current returns matched than this fraction: no velocity measurement (a
    detection of another obstacle than the track's, or a side mostly new to it)."""
    max_interval: float = 0.5
    """Returns kept longer than this are not registered against [s] (a long-hidden obstacle
    is found again by its centre)."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        **TrackerConfig.LIMITS,
        "residual_weight": (0.0, 1000.0),
        "registration_sigma": (1e-4, 1.0),
        "registration_trim": (0.01, 2.0),
        "registration_coarse_trim": (0.01, 5.0),
        "registration_prior": (1e-6, 100.0),
        "registration_iterations": (1, 50),
        "min_matched": (1, 720),
        "min_matched_fraction": (0.0, 1.0),
        "max_interval": (0.01, 10.0),
    }


class RegisteredTracker(ObstacleTracker):
    """`kalman` plus velocity from registered returns (see the module)."""

    name = "registered"
    Config = RegisteredTrackerConfig
    PER_TRACK: ClassVar[tuple[str, ...]] = (*ObstacleTracker.PER_TRACK, "kept_at")

    def __init__(self, cfg: RegisteredTrackerConfig, detector) -> None:
        super().__init__(cfg, detector)
        self.kept_at = np.zeros(0)  # when each track's kept returns were seen [s]
        self.kept = np.zeros((0, 2))  # every track's returns of the last scan it was seen in
        self.kept_owner = np.zeros(0, dtype=np.int64)  # the track id of each

    def _next_scan(self, time: float, scan: np.ndarray, pose: np.ndarray) -> tuple[Detections, float, np.ndarray]:
        det, dt, var = super()._next_scan(time, scan, pose)
        return det, dt, var + (self.cfg.residual_weight * det.residuals) ** 2

    def _motion(self, k: np.ndarray, columns: np.ndarray, det: Detections, time: float):
        cfg = self.cfg
        interval = time - self.kept_at[k]
        usable = (interval > 1e-6) & (interval <= cfg.max_interval)
        k, columns, interval = k[usable], columns[usable], interval[usable]
        if not len(k):
            return None
        point_of = det.segment_of_point
        current, current_mask = padded(det.points, point_of, columns)
        earlier, earlier_mask = padded(self.kept, self.kept_owner, self.ids[k])
        found = register(
            current,
            current_mask,
            earlier,
            earlier_mask,
            self.v[k] * interval[:, None],  # the predicted motion
            sigma=cfg.registration_sigma,
            trim=cfg.registration_trim,
            coarse_trim=cfg.registration_coarse_trim,
            prior=cfg.registration_prior,
            iterations=cfg.registration_iterations,
        )
        ok = (found.matched >= cfg.min_matched) & (found.matched >= cfg.min_matched_fraction * current_mask.sum(axis=1))
        if not ok.any():
            return None
        velocity = snap_array(found.shift[ok] / interval[ok, None], STATE_RESOLUTION)
        return k[ok], velocity, found.variance[ok] / (interval[ok, None] ** 2)

    def _remember(
        self, det: Detections, matched: np.ndarray, columns: np.ndarray, born: np.ndarray, time: float
    ) -> None:
        n_born = len(born)
        if n_born:
            self.kept_at = np.concatenate([self.kept_at, np.full(n_born, time)])
        self.kept_at[np.isin(self.ids, matched)] = time
        fresh_ids = np.concatenate([matched, self.ids[len(self.ids) - n_born :]])
        fresh_columns = np.concatenate([columns, born])
        # Tracks dropped this scan and those seen again lose their earlier returns.
        stay = np.isin(self.kept_owner, self.ids) & ~np.isin(self.kept_owner, fresh_ids)
        slot = np.full(len(det) + 1, -1, dtype=np.int64)  # the last: returns of rejected segments
        slot[fresh_columns] = fresh_ids
        segment = det.segment_of_point
        owner = slot[np.where(segment >= 0, segment, len(det))]
        new = owner >= 0
        self.kept = np.concatenate([self.kept[stay], det.points[new]])
        self.kept_owner = np.concatenate([self.kept_owner[stay], owner[new]])
