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
  unmatched for a while and matched again to its old track does not count), with the
  pairs matched afresh each tick (`id_switches`, every committed row's count);
- identity switches as CLEAR-MOT counts them (`id_switches_mot`; Bernardin and
  Stiefelhagen, 2008): last tick's pair is kept while its track is still within
  `MATCH_DISTANCE` of its obstacle, and only the rest are matched afresh, so two tracks near
  one obstacle do not trade it back and forth, each trade a switch. Added after the
  committed sweeps ran (issue 57): rows written before it lack it, and `--verify` notes the
  added measure rather than calling it a difference.
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
    return (*gated_assignment(d), d)


def gated_assignment(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Hungarian method's one-to-one pairs of an (n, k) distance matrix, each within
    `MATCH_DISTANCE`: (rows, columns)."""
    rows, cols = linear_sum_assignment(np.where(d <= MATCH_DISTANCE, d, 1e6))
    ok = d[rows, cols] <= MATCH_DISTANCE
    return rows[ok], cols[ok]


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
    "id_switches_mot",
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
        self.paired = np.full(n_obstacles, -1, dtype=np.int64)  # last tick's track of each (CLEAR-MOT)
        self.last_id_mot = np.full(n_obstacles, -1, dtype=np.int64)
        self.switches_mot = 0
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
            self.paired[:] = -1
            return
        rows, cols, d = matched_pairs(tracks.positions, positions)
        self._clear_mot(tracks.ids, d)
        self.n_matched_tracks += len(rows)
        self.found += int(in_view[cols].sum())
        self._pos.append(d[rows, cols])
        self._vel.append(np.sqrt(((tracks.velocities[rows] - velocities[cols]) ** 2).sum(axis=-1)))
        ids = tracks.ids[rows]
        before = self.last_id[cols]
        self.switches += int(((before >= 0) & (before != ids)).sum())
        self.last_id[cols] = ids

    def _clear_mot(self, ids: np.ndarray, d: np.ndarray) -> None:
        """CLEAR-MOT's correspondence for one tick, given the tracks' `ids` and their (n, k)
        distances `d` to the obstacles: last tick's pairs kept while within the match
        distance, the rest matched by the Hungarian method; a matched obstacle whose track
        is not the last one it had is a switch."""
        is_last = ids[:, None] == self.paired[None, :]  # (n, k): track i was obstacle j's last tick
        kept = (is_last & (d <= MATCH_DISTANCE)).any(axis=0)
        track_kept = (is_last[:, kept]).any(axis=1)
        pair = np.where(kept, self.paired, -1)
        free_rows, free_cols = np.flatnonzero(~track_kept), np.flatnonzero(~kept)
        if len(free_rows) and len(free_cols):
            r, c = gated_assignment(d[np.ix_(free_rows, free_cols)])
            pair[free_cols[c]] = ids[free_rows[r]]
        matched = pair >= 0
        self.switches_mot += int((matched & (self.last_id_mot >= 0) & (self.last_id_mot != pair)).sum())
        self.last_id_mot[matched] = pair[matched]
        self.paired = pair

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
            "id_switches_mot": self.switches_mot,
            "ticks": self.ticks,
        }


def beams_per_obstacle(geom_ids: np.ndarray, obstacle_of_geom: np.ndarray, n_obstacles: int) -> np.ndarray:
    """How many beams of a cast ended on each obstacle (n_obstacles,)."""
    hit = obstacle_of_geom[geom_ids[geom_ids >= 0]]
    return np.bincount(hit[hit >= 0], minlength=n_obstacles)
