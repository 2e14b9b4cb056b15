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

import numpy as np

from dynabarn.world import EndBehavior, Interpolation, WorldSpec


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
        n = len(world.obstacles)
        self.n_obstacles = n
        k_max = max((len(o.trajectory.times) for o in world.obstacles), default=2)
        self.n_keyframes = np.array([len(o.trajectory.times) for o in world.obstacles], dtype=np.int64)
        # Padded with +inf times so searches never select the padding.
        self.times = np.full((n, k_max), np.inf)
        self.points = np.zeros((n, k_max, 2))
        self.tangents = np.zeros((n, k_max, 2))
        for i, o in enumerate(world.obstacles):
            k = len(o.trajectory.times)
            self.times[i, :k] = o.trajectory.times
            self.points[i, :k] = o.trajectory.xy
            self.points[i, k:] = o.trajectory.xy[-1]
            self.tangents[i, :k] = _catmull_rom_tangents(o.trajectory.xy)
        self.durations = self.times[np.arange(n), self.n_keyframes - 1] if n else np.zeros(0)
        self._rows = np.arange(n)
        self._last_segment = np.maximum(self.n_keyframes - 2, 0)

    def local_time(self, t: float | np.ndarray) -> np.ndarray:
        """Each obstacle's clock at world time(s) t [s]: shape (n_obstacles,) or (T, n_obstacles)."""
        tl = np.asarray(t, dtype=np.float64)[..., None] + self.clock_offset + np.zeros(self.n_obstacles)
        if self.end_behavior is EndBehavior.LOOP:
            return np.mod(tl, self.durations)
        return np.minimum(tl, self.durations)

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions (n_obstacles, 2) [m] and velocities (n_obstacles, 2) [m/s] at time t."""
        return self._evaluate(self.local_time(t))

    def positions_at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (T, n_obstacles, 2) at each of `times` (T,) [s], at once."""
        return self._evaluate(self.local_time(np.asarray(times, dtype=np.float64)))

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
        # Segment index per obstacle: the last keyframe at or before tl.
        seg = (self.times <= tl[..., None]).sum(axis=-1) - 1
        np.clip(seg, 0, self._last_segment, out=seg)
        r = self._rows
        t0 = self.times[r, seg]
        dt = self.times[r, seg + 1] - t0
        u = np.clip((tl - t0) / dt, 0.0, 1.0)[..., None]
        p0 = self.points[r, seg]
        p1 = self.points[r, seg + 1]
        dt = dt[..., None]
        if self.interpolation is Interpolation.LINEAR:
            return p0 + (p1 - p0) * u, (p1 - p0) / dt
        m0 = self.tangents[r, seg]
        m1 = self.tangents[r, seg + 1]
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
