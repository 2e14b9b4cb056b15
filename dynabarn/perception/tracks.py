"""`Tracks`: the tracker's picture of the moving obstacles at one instant, and their
constant-velocity future."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class Tracks:
    """Tracked obstacles in the world frame, at `time`.

    The filter is a constant-velocity Kalman filter per axis (x and y independent, so each
    axis has a 2 x 2 covariance of position and velocity).

    Attributes:
        time: when this estimate holds (the scan's time) [s].
        ids: (n,) track identities, never reused within an episode.
        positions: (n, 2) centres [m].
        velocities: (n, 2) [m/s].
        sizes: (n,) radius of a circle around each obstacle [m].
        position_var: (n, 2) variance of x and y [m^2].
        velocity_var: (n, 2) variance of vx and vy [m^2/s^2].
        position_velocity_cov: (n, 2) covariance of x with vx, y with vy [m^2/s].
        age: (n,) seconds since each track was born.
        last_seen: (n,) time of each track's last detection [s] (below `time`: coasting).
    """

    time: float
    ids: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    sizes: np.ndarray
    position_var: np.ndarray
    velocity_var: np.ndarray
    position_velocity_cov: np.ndarray
    age: np.ndarray
    last_seen: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def covariances(self) -> np.ndarray:
        """(n, 4, 4) covariance of (x, y, vx, vy)."""
        n = len(self)
        cov = np.zeros((n, 4, 4))
        for axis in (0, 1):
            cov[:, axis, axis] = self.position_var[:, axis]
            cov[:, axis + 2, axis + 2] = self.velocity_var[:, axis]
            cov[:, axis, axis + 2] = cov[:, axis + 2, axis] = self.position_velocity_cov[:, axis]
        return cov

    def predict(self, t: float | np.ndarray) -> np.ndarray:
        """Positions at world time(s) t at constant velocity: (n, 2) for one time, (T, n, 2)
        for an array of T times (`ObstacleState.predict`'s shapes)."""
        t = np.asarray(t, dtype=np.float64)
        dt = t - self.time
        if dt.ndim == 0:
            return self.positions + self.velocities * float(dt)
        return self.positions[None] + self.velocities[None] * dt[:, None, None]

    def position_std(self, t: float | np.ndarray) -> np.ndarray:
        """Standard deviation of the predicted position (the larger axis) at time(s) t:
        (n,) or (T, n) [m]."""
        dt = np.asarray(t, dtype=np.float64) - self.time
        dt = dt[..., None] if dt.ndim else dt
        dt = dt[..., None]
        var = self.position_var + 2.0 * dt * self.position_velocity_cov + dt * dt * self.velocity_var
        return np.sqrt(np.maximum(var, 0.0)).max(axis=-1)

    @staticmethod
    def empty(time: float = 0.0) -> Tracks:
        z2, z1 = np.zeros((0, 2)), np.zeros(0)
        return Tracks(time, np.zeros(0, dtype=np.int64), z2, z2, z1, z2, z2, z2, z1, z1)
