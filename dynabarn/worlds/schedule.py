"""Schedule playback: every obstacle's position and velocity at time t, vectorised.

The keyframes of all obstacles are padded into (n_obstacles, max_keyframes) arrays once,
so one call evaluates all obstacles, at one time or at many, with a handful of numpy
operations and no Python loop over obstacles. The runner evaluates every physics step of
a control period in one `positions_at` call.

Interpolation:
- `linear`: straight lines at constant speed between waypoints (the paper).
- `spline`: Gazebo's `PoseAnimation` (gazebo-classic 9, ignition-math `Spline`): a cubic
  Hermite segment between keyframes k and k+1 evaluated at the time fraction
  u = (t - t_k) / (t_{k+1} - t_k), with Catmull-Rom tangents (tension 0)
  m_k = (p_{k+1} - p_{k-1}) / 2, m_0 = (p_1 - p_0) / 2, m_last = (p_last - p_{last-1}) / 2
  (a closed curve, first point == last, uses the wrap-around neighbour instead).

End behaviour: `loop` wraps time modulo each obstacle's duration (Gazebo's loop=true
jumps back to the first keyframe), `hold` stays at the last waypoint.
A clock offset (seconds) shifts every obstacle's clock; trials use it.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from dynabarn.worlds.spec import EndBehavior, Interpolation, WorldSpec

_STRIDE = 1.0e6
"""Seconds between obstacles in the flat key array; schedules are far shorter."""


@dataclass(frozen=True)
class Keyframes:
    """A world's keyframes as the player evaluates them (read only: shared by its players)."""

    n: int
    n_keyframes: np.ndarray
    durations: np.ndarray
    seg_lo: np.ndarray
    seg_hi: np.ndarray
    stride_offsets: np.ndarray
    flat_key: np.ndarray | None
    flat_t: np.ndarray | None
    flat_p: np.ndarray | None
    flat_m: np.ndarray | None


_KEPT_WORLDS = 256
_kept: OrderedDict[int, tuple[WorldSpec, Keyframes]] = OrderedDict()


def keyframes_of(world: WorldSpec) -> Keyframes:
    """The world's keyframe arrays, built once per world object: every episode's player
    (one per trial) shares them; only the clock offset is its own."""
    hit = _kept.get(id(world))
    if hit is not None and hit[0] is world:
        _kept.move_to_end(id(world))
        return hit[1]
    obstacles = world.obstacles
    n = len(obstacles)
    n_keyframes = np.array([len(o.trajectory.times) for o in obstacles], dtype=np.int64)
    # All keyframes in one flat array, obstacle i's times shifted by i * _STRIDE, so one
    # searchsorted finds every obstacle's segment at every query time at once.
    start = np.concatenate([[0], np.cumsum(n_keyframes)[:-1]]).astype(np.int64)
    table = Keyframes(
        n=n,
        n_keyframes=n_keyframes,
        durations=np.array([o.trajectory.duration for o in obstacles], dtype=np.float64),
        seg_lo=start,
        seg_hi=start + np.maximum(n_keyframes - 2, 0),
        stride_offsets=np.arange(n) * _STRIDE,
        flat_key=np.concatenate([o.trajectory.times + i * _STRIDE for i, o in enumerate(obstacles)]) if n else None,
        flat_t=np.concatenate([o.trajectory.times for o in obstacles]) if n else None,
        flat_p=np.concatenate([o.trajectory.xy for o in obstacles]) if n else None,
        flat_m=np.concatenate([_catmull_rom_tangents(o.trajectory.xy) for o in obstacles]) if n else None,
    )
    for a in vars(table).values():
        if isinstance(a, np.ndarray):
            a.flags.writeable = False  # shared by every player of the world
    _kept[id(world)] = (world, table)  # the world kept with it: its id cannot be reused meanwhile
    while len(_kept) > _KEPT_WORLDS:
        _kept.popitem(last=False)
    return table


class SchedulePlayer:
    """Vectorised playback of a world's obstacle schedules.

    Args:
        world: the world whose obstacles to play.
        clock_offset: seconds added to every obstacle's clock [s].
    """

    def __init__(self, world: WorldSpec, *, clock_offset: float = 0.0) -> None:
        self.interpolation = Interpolation(world.interpolation)
        self.end_behavior = EndBehavior(world.end_behavior)
        self.clock_offset = float(clock_offset)
        k = self.keyframes = keyframes_of(world)  # public: a batch of players joins them (`schedule_batch`)
        self.n_obstacles = k.n
        self.n_keyframes, self.durations = k.n_keyframes, k.durations
        self._seg_lo, self._seg_hi, self._stride_offsets = k.seg_lo, k.seg_hi, k.stride_offsets
        if k.n:
            self._flat_key, self._flat_t, self._flat_p, self._flat_m = k.flat_key, k.flat_t, k.flat_p, k.flat_m

    def local_time(self, t: float | np.ndarray) -> np.ndarray:
        """Each obstacle's clock at world time(s) t [s]: shape (n_obstacles,) or (T, n_obstacles)."""
        tl = np.asarray(t, dtype=np.float64)[..., None] + self.clock_offset  # broadcasts to (..., n)
        if self.end_behavior is EndBehavior.LOOP:
            return np.mod(tl, self.durations)
        return np.minimum(tl, self.durations)

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions (n_obstacles, 2) [m] and velocities (n_obstacles, 2) [m/s] at time t."""
        return self._evaluate(self.local_time(t))

    def positions_at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (T, n_obstacles, 2) at each of `times` (T,) [s], at once."""
        return self._evaluate(self.local_time(np.asarray(times, dtype=np.float64)))

    def positions_at_local(self, local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (T, n, 2) at per-obstacle schedule times local (T, n) [s]
        (before the clock offset and the end behaviour), for obstacles with their own clocks."""
        tl = np.asarray(local, dtype=np.float64) + self.clock_offset
        tl = np.mod(tl, self.durations) if self.end_behavior is EndBehavior.LOOP else np.minimum(tl, self.durations)
        return self._evaluate(tl)

    def max_speed(self) -> float:
        """A bound [m/s] on every obstacle's speed between the jumps of `clock_wraps`: each
        segment's largest |d position / d t| (linear: its speed; spline: the Hermite
        derivative's |h00'| <= 1.5, |h10'|, |h11'| <= 1 on [0, 1]). inf for a segment without
        duration; 0 without segments."""
        if self.n_obstacles == 0:
            return 0.0
        t, p, m = self._flat_t, self._flat_p, self._flat_m
        within = np.ones(len(t) - 1, dtype=bool)  # consecutive keyframes of one obstacle
        between = self._seg_lo[1:] - 1
        within[between[(between >= 0) & (between < len(within))]] = False
        if not within.any():
            return 0.0
        lo = np.flatnonzero(within)
        reach = np.hypot(*(p[lo + 1] - p[lo]).T)
        if self.interpolation is Interpolation.SPLINE:
            reach = 1.5 * reach + np.hypot(*m[lo].T) + np.hypot(*m[lo + 1].T)
        span = t[lo + 1] - t[lo]
        with np.errstate(divide="ignore", invalid="ignore"):
            speed = np.where(span > 0.0, reach / np.where(span > 0.0, span, 1.0), np.inf)
        return float(speed.max())

    def clock_wraps(self, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
        """(W,) whether some obstacle's clock wraps in [t0, t1] (W,) [s]: where a looping
        path that does not close jumps back to its first keyframe (`max_speed` does not
        hold across). Never with `hold`."""
        t0, t1 = np.asarray(t0, dtype=np.float64), np.asarray(t1, dtype=np.float64)
        if self.end_behavior is not EndBehavior.LOOP or self.n_obstacles == 0:
            return np.zeros(t0.shape, dtype=bool)
        shortest = float(self.durations.min())
        return (self.local_time(t1) < self.local_time(t0)).any(axis=-1) | (t1 - t0 >= shortest)

    def positions_into(self, t: float, pos: np.ndarray, vel: np.ndarray | None = None) -> None:
        """Write positions (and velocities) at time t into preallocated (n, 2) arrays."""
        p, v = self.state(t)
        pos[...] = p
        if vel is not None:
            vel[...] = v

    def _evaluate(self, tl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (..., n, 2) for local clocks tl (..., n)."""
        if self.n_obstacles == 0:
            shape = (*tl.shape, 2)
            return np.zeros(shape), np.zeros(shape)
        # Flat index of the last keyframe at or before tl, for every obstacle and time.
        seg = np.searchsorted(self._flat_key, tl + self._stride_offsets, side="right") - 1
        np.clip(seg, self._seg_lo, self._seg_hi, out=seg)
        return interpolate(self.interpolation, self._flat_t, self._flat_p, self._flat_m, tl, seg)


def interpolate(interpolation: Interpolation, flat_t, flat_p, flat_m, tl: np.ndarray, seg: np.ndarray):
    """Positions and velocities (..., n, 2) at clocks tl (..., n) in keyframe segments seg
    (flat indices into the keyframe times flat_t, positions flat_p and tangents flat_m)."""
    # np.take, not flat_p[seg]: numpy's fancy indexing of rows is ten times slower.
    nxt = seg + 1
    t0 = np.take(flat_t, seg)
    dt = np.take(flat_t, nxt) - t0
    u = np.clip((tl - t0) / dt, 0.0, 1.0)[..., None]
    p0 = np.take(flat_p, seg, axis=0)
    p1 = np.take(flat_p, nxt, axis=0)
    dt = dt[..., None]
    if interpolation is Interpolation.LINEAR:
        d = p1 - p0
        return p0 + d * u, d / dt
    m0 = np.take(flat_m, seg, axis=0)
    m1 = np.take(flat_m, nxt, axis=0)
    u2 = u * u
    u3 = u2 * u
    pos = (2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1
    vel = ((6 * u2 - 6 * u) * p0 + (3 * u2 - 4 * u + 1) * m0 + (-6 * u2 + 6 * u) * p1 + (3 * u2 - 2 * u) * m1) / dt
    return pos, vel


def _catmull_rom_tangents(p: np.ndarray) -> np.ndarray:
    """Tangents per keyframe as ignition-math's Spline::RecalcTangents (tension 0)."""
    n = len(p)
    m = np.empty_like(p)
    if n < 2:
        m[:] = 0.0
        return m
    closed = bool(np.array_equal(p[0], p[-1]))
    m[1:-1] = 0.5 * (p[2:] - p[:-2])
    if closed and n > 2:
        m[0] = 0.5 * (p[1] - p[-2])
        m[-1] = m[0]
    else:
        m[0] = 0.5 * (p[1] - p[0])
        m[-1] = 0.5 * (p[-1] - p[-2])
    return m
