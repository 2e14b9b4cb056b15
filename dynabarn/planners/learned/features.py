"""What a student policy sees, as named options, in numpy (`FeatureConfig`, `Features`).

The paper's 722 inputs come first: the 720 ranges and the local goal (g_x, g_y) from the
Dijkstra plan `lookahead` metres ahead. The options beyond them (each a named departure
in the results where it is used):

- `history`: the last K scans before this one, `history_every` ticks apart, each
  min-pooled over `history_pool` neighbouring beams (a 720-beam frame every tick would
  quadruple the inputs; the nearest return in each pool is what avoidance needs). Motion
  becomes visible as the difference between frames (as in LfH-CP and Dyna-LfLH).
- `static_map`: the known map (walls and standing cylinders, what `predictive` and the
  oracles plan on) as the laser would see it alone from the robot's pose
  (`perception.MapScan`), min-pooled as the history frames are: where the scan reads
  shorter, something the map does not hold is in the way.
- `velocity`: the robot's measured forward speed and turn rate.
- `tracks`: the N nearest tracks of the laser tracker (`dynabarn.perception`): position
  and velocity in the robot frame, size, and a flag that the slot holds a track; empty
  slots read zero.

Every input is scaled here to about [-1, 1] (ranges by `range_scale`, clipped there:
beyond 10 m nothing needs avoiding yet), so the network takes the vector as it is.
The builder keeps its buffers between ticks: nothing is allocated per step but the
output vector.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from dynabarn.interfaces import CheckedConfig, EpisodeInfo, Observation, config_from_kwargs, recorded_config
from dynabarn.perception import MapScan, ObstacleTracker, TrackerConfig
from dynabarn.perception.trackers import make_tracker
from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.planners.tracking import with_tracker
from dynabarn.robot import JACKAL

TRACK_FIELDS = 6
"""Per track slot: x, y, vx, vy (robot frame), size, present."""
SPEED_SCALE = 2.0
"""Velocities [m/s] and turn rates [rad/s] are divided by this."""
_TURNED_LOW = np.array([-1.0, -1.0, -2.0, -2.0])
"""Lower bounds of a track slot's scaled (x, y, vx, vy); the upper are their negatives."""


@dataclass
class FeatureConfig(CheckedConfig):
    history: int = 0
    """Earlier scans given beside the current one (0: the paper's single scan)."""
    history_every: int = 2
    """Control ticks between history frames (2: 0.2 s)."""
    history_pool: int = 4
    """Beams min-pooled into one history input (720 / 4 = 180 per frame)."""
    static_map: bool = False
    """Give the known map's ranges along the pooled beams (`perception.MapScan`)."""
    velocity: bool = False
    """Give the robot's measured (v, w)."""
    tracks: int = 0
    """Nearest tracks of the laser tracker given (0: no tracker)."""
    range_scale: float = 10.0
    """Ranges are clipped here and divided by it [m]."""
    lookahead: float = 2.0
    """Local goal distance along the global plan [m]."""
    tracker: TrackerConfig = field(default_factory=TrackerConfig)

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "history": (0, 16),
        "history_every": (1, 50),
        "history_pool": (1, 720),
        "tracks": (0, 64),
        "range_scale": (0.5, 30.0),
        "lookahead": (0.1, 30.0),
    }

    @classmethod
    def from_dict(cls, d: dict) -> FeatureConfig:
        d = dict(d)
        tracker = d.pop("tracker", {})
        built = with_tracker({"tracker": tracker}, "features")
        return config_from_kwargs(cls, {**d, **built}, "features")

    def to_dict(self) -> dict:
        return recorded_config(self)

    def size(self, n_beams: int = JACKAL.laser_beams) -> int:
        """Length of the feature vector for a laser of `n_beams` beams (the Jackal's by default)."""
        return self.layout(n_beams)["size"]

    def layout(self, n_beams: int = JACKAL.laser_beams) -> dict:
        """Where each input lies in the vector (what `set_encoder` splits it by): the beams'
        count and pooled width, (start, end) of the history frames, the map's pooled ranges,
        the velocity and the track slots (the map, the velocity and the tracks None where not
        given), and the vector's size."""
        pooled = math.ceil(n_beams / self.history_pool)
        i = n_beams + 2
        history = (i, i + self.history * pooled)
        i = history[1]
        static_map = (i, i + pooled) if self.static_map else None
        i += pooled if self.static_map else 0
        velocity = (i, i + 2) if self.velocity else None
        i += 2 if self.velocity else 0
        tracks = (i, i + self.tracks * TRACK_FIELDS) if self.tracks else None
        i += self.tracks * TRACK_FIELDS
        return {
            "beams": n_beams,
            "pooled": pooled,
            "history": history,
            "static_map": static_map,
            "velocity": velocity,
            "tracks": tracks,
            "size": i,
        }

    def names(self) -> list[str]:
        """The option names in use, for tables ("scan+goal", "history 2", ...)."""
        out = ["scan+goal"]
        if self.history:
            out.append(f"history {self.history}x{self.history_every * 0.1:.1f}s")
        if self.static_map:
            out.append("map")
        if self.velocity:
            out.append("velocity")
        if self.tracks:
            out.append(f"tracks {self.tracks}")
        return out


class Features:
    """One episode's feature builder: call `reset(info)` per episode, then once per tick."""

    def __init__(self, cfg: FeatureConfig) -> None:
        self.cfg = cfg
        self.tracker: ObstacleTracker | None = None
        self.global_planner: GlobalPlanner | None = None
        self.map_scan: MapScan | None = None
        self.last_tracks = None

    def reset(self, info: EpisodeInfo) -> None:
        c = self.cfg
        self.n_beams = len(info.laser_angles)
        self.size = c.size(self.n_beams)
        self.global_planner = GlobalPlanner.for_robot(info.walls, info.goal, info.footprint, info.static_obstacles)
        self.tracker = make_tracker(c.tracker, info) if c.tracks else None
        self.map_scan = MapScan(info) if c.static_map else None
        self.last_tracks = None
        pooled = self._pooled = math.ceil(self.n_beams / c.history_pool)
        # The scan (and the map's ranges) padded to whole pools with 1.0 (far away) beyond
        # the last beam.
        self._padded = np.ones(pooled * c.history_pool)
        # Ring of pooled frames: the last history * history_every ticks (frame 0 repeated
        # until the episode is old enough, as a robot standing still would see).
        self._ring = np.zeros((max(1, c.history * c.history_every), pooled))
        self._ticks = 0

    def local_goal(self, obs: Observation) -> np.ndarray:
        return self.global_planner.local_goal_in_robot(obs.pose, self.cfg.lookahead)

    def __call__(self, obs: Observation) -> np.ndarray:
        c = self.cfg
        out = np.zeros(self.size)
        scan = np.minimum(obs.scan, c.range_scale) / c.range_scale
        n = self.n_beams
        out[:n] = scan
        out[n : n + 2] = self.local_goal(obs) / c.lookahead
        i = n + 2
        if c.history:
            self._padded[:n] = scan
            pooled = self._padded.reshape(-1, c.history_pool).min(axis=1)
            ring, m = self._ring, len(self._ring)
            if self._ticks == 0:
                ring[:] = pooled
            # Frames k * every ticks ago, k = 1..history, read before this tick is stored.
            for k in range(1, c.history + 1):
                out[i : i + ring.shape[1]] = ring[(self._ticks - k * c.history_every) % m]
                i += ring.shape[1]
            ring[self._ticks % m] = pooled
        self._ticks += 1
        if c.static_map:
            self._padded[:n] = np.minimum(self.map_scan(obs.pose), c.range_scale) / c.range_scale
            out[i : i + self._pooled] = self._padded.reshape(-1, c.history_pool).min(axis=1)
            i += self._pooled
        if c.velocity:
            out[i : i + 2] = obs.velocity / SPEED_SCALE
            i += 2
        if c.tracks:
            out[i : i + c.tracks * TRACK_FIELDS] = self._track_slots(obs)
        return out

    def _track_slots(self, obs: Observation) -> np.ndarray:
        c = self.cfg
        tracks = self.last_tracks = self.tracker.update(obs.time, obs.scan, obs.pose)
        slots = np.zeros((c.tracks, TRACK_FIELDS))
        if len(tracks):
            x, y, yaw = obs.pose
            cs, sn = math.cos(yaw), math.sin(yaw)
            d = tracks.positions - (x, y)
            v = tracks.velocities
            # Robot-frame positions and velocities, one (n, 4) array: [x, y, vx, vy].
            turned = np.empty((len(tracks), 4))
            turned[:, 0] = cs * d[:, 0] + sn * d[:, 1]
            turned[:, 1] = -sn * d[:, 0] + cs * d[:, 1]
            turned[:, 2] = cs * v[:, 0] + sn * v[:, 1]
            turned[:, 3] = -sn * v[:, 0] + cs * v[:, 1]
            gap = np.hypot(turned[:, 0], turned[:, 1]) - tracks.sizes
            # Nearest first; equal gaps by track id, so the order never depends on the sort.
            order = np.lexsort((tracks.ids, gap))[: c.tracks]
            k = len(order)
            # np.clip's bits without its Python wrapper: positions within +-1, speeds +-2.
            chosen = turned[order]
            chosen /= (c.range_scale, c.range_scale, SPEED_SCALE, SPEED_SCALE)
            np.maximum(chosen, _TURNED_LOW, out=chosen)
            np.minimum(chosen, -_TURNED_LOW, out=chosen)
            slots[:k, 0:4] = chosen
            slots[:k, 4] = tracks.sizes[order]
            slots[:k, 5] = 1.0
        return slots.ravel()
