"""How well a planner's tracker saw the moving obstacles, scored against the truth the
simulator knows (the CLEAR-MOT way: match, then count and measure).

Every control tick the planner's tracks (`Planner.tracks()`) are matched one-to-one with
the true obstacle centres by the Hungarian method, a pair counting only within
`MATCH_DISTANCE` (an obstacle's diameter). Over the episode:

- recall: of the obstacles in view (at least `MIN_BEAMS` beams of the noise-free scan end
  on them: in range, inside the 270 degree field of view, not hidden), the fraction with a
  matched track;
- precision: of the tracks, the fraction matched with an obstacle (in view or not: a
  coasting track of a hidden obstacle is right);
- position and velocity errors of the matched pairs: median and 95th percentile;
- identity switches: how often an obstacle's matched track changes identity (an obstacle
  unmatched for a while and matched again to its old track does not count).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

MATCH_DISTANCE = 1.0
"""[m] A track farther than this from an obstacle's centre is not that obstacle."""


def matched_pairs(tracked: np.ndarray, true: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tracked centres (n, 2) matched one to one with true centres (k, 2) by the Hungarian
    method, a pair counting only within `MATCH_DISTANCE`: (the tracks' rows, the obstacles'
    rows, the (n, k) distances)."""
    d = np.sqrt(((tracked[:, None, :] - true[None, :, :]) ** 2).sum(axis=-1))
    rows, cols = linear_sum_assignment(np.where(d <= MATCH_DISTANCE, d, 1e6))
    ok = d[rows, cols] <= MATCH_DISTANCE
    return rows[ok], cols[ok], d


MIN_BEAMS = 3
"""An obstacle is in view when at least this many beams end on it."""
TRACKING_FIELDS = (
    "recall",
    "precision",
    "position_error_median",
    "position_error_p95",
    "velocity_error_median",
    "velocity_error_p95",
    "id_switches",
    "ticks",
)
"""The keys of `EpisodeResult.tracking`."""


class TrackScorer:
    """Accumulates one episode's tracking quality, one tick at a time."""

    def __init__(self, n_obstacles: int) -> None:
        self.last_id = np.full(n_obstacles, -1, dtype=np.int64)
        self.in_view = 0
        self.found = 0
        self.n_tracks = 0
        self.n_matched_tracks = 0
        self.switches = 0
        self.ticks = 0
        self._pos: list[np.ndarray] = []
        self._vel: list[np.ndarray] = []

    def add(self, tracks, positions: np.ndarray, velocities: np.ndarray, in_view: np.ndarray) -> None:
        """One tick: `tracks` (with `ids`, `positions`, `velocities`) against the true
        centres (n, 2), velocities (n, 2) and which obstacles are in view (n,)."""
        self.ticks += 1
        self.in_view += int(in_view.sum())
        self.n_tracks += len(tracks.ids)
        if not len(tracks.ids) or not len(positions):
            return
        rows, cols, d = matched_pairs(tracks.positions, positions)
        self.n_matched_tracks += len(rows)
        self.found += int(in_view[cols].sum())
        self._pos.append(d[rows, cols])
        self._vel.append(np.sqrt(((tracks.velocities[rows] - velocities[cols]) ** 2).sum(axis=-1)))
        ids = tracks.ids[rows]
        before = self.last_id[cols]
        self.switches += int(((before >= 0) & (before != ids)).sum())
        self.last_id[cols] = ids

    def summary(self) -> dict:
        """`EpisodeResult.tracking`: the fields of `TRACKING_FIELDS` (errors None without matches)."""
        pos = np.concatenate(self._pos) if self._pos else np.zeros(0)
        vel = np.concatenate(self._vel) if self._vel else np.zeros(0)

        def stat(x: np.ndarray, q: float) -> float | None:
            return float(np.percentile(x, q)) if len(x) else None

        return {
            "recall": self.found / self.in_view if self.in_view else None,
            "precision": self.n_matched_tracks / self.n_tracks if self.n_tracks else None,
            "position_error_median": stat(pos, 50),
            "position_error_p95": stat(pos, 95),
            "velocity_error_median": stat(vel, 50),
            "velocity_error_p95": stat(vel, 95),
            "id_switches": self.switches,
            "ticks": self.ticks,
        }


def beams_per_obstacle(geom_ids: np.ndarray, obstacle_of_geom: np.ndarray, n_obstacles: int) -> np.ndarray:
    """How many beams of a cast ended on each obstacle (n_obstacles,)."""
    hit = obstacle_of_geom[geom_ids[geom_ids >= 0]]
    return np.bincount(hit[hit >= 0], minlength=n_obstacles)
