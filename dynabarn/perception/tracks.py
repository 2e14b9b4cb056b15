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
        headings: (n,) heading of each obstacle's sides [rad], None from a tracker that
            fits circles only (`kalman`).
        half_sizes: (n, 2) half sizes of each obstacle's bounding rectangle along and across
            its heading [m], None with `headings`.
        half_size_std: (n, 2) how uncertain each half size is [m] (large where the laser has
            not yet seen that extent whole), None with `headings`.
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
    headings: np.ndarray | None = None
    half_sizes: np.ndarray | None = None
    half_size_std: np.ndarray | None = None
    extent_sigmas: float = 1.0
    """Standard deviations of its half sizes each outline is grown by when a planner covers
    it with circles (`covering_circles`): the tracker's setting (`shape.extent_sigmas`), so
    that a planner reads no tracker's configuration."""

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

    def padded_sizes(self, t: float | np.ndarray, sigmas: float, max_padding: float) -> np.ndarray:
        """Each track's radius grown by `sigmas` standard deviations of its predicted position
        at time(s) t (`position_std`), by at most `max_padding` [m]: (n,) or (T, n) (t's shape,
        then the tracks). What a planner keeps clear of when it plans against the tracker's
        uncertainty rather than a centre and a radius; `sigmas` 0 gives the sizes as they are."""
        if sigmas == 0.0:
            return np.broadcast_to(self.sizes, np.shape(t) + self.sizes.shape).copy()
        return self.sizes + np.minimum(max_padding, sigmas * self.position_std(t))

    def covering_circles(self, extent_sigmas: float | None = None) -> Tracks:
        """These tracks with every outline replaced by circles that cover it (each circle a
        track of its own: the same identity, velocity and uncertainty, its centre offset
        along the outline's long axis); tracks without outlines unchanged (this object).
        `extent_sigmas`: the tracker's (`self.extent_sigmas`) unless given.

        An outline of half sizes L >= S (grown by `extent_sigmas` standard deviations of
        each) gets c = 1 + ceil(2 (L - S) / (1.5 S)) circles of radius sqrt(S^2 + (d/2)^2),
        d = 2 (L - S) / (c - 1) apart: they cover the rectangle, corners included, with at
        most a quarter of S to spare (a cylinder: one circle of its radius). What plans
        against circles (the oracle's search, DWA, TEB) plans against the outline so.
        """
        if self.half_sizes is None or not len(self):
            return self
        extent_sigmas = self.extent_sigmas if extent_sigmas is None else extent_sigmas
        half = self.half_sizes + extent_sigmas * (0.0 if self.half_size_std is None else self.half_size_std)
        along = half[:, 0] >= half[:, 1]
        long_, short = np.where(along, half[:, 0], half[:, 1]), np.maximum(np.minimum(half[:, 0], half[:, 1]), 1e-3)
        count = 1 + np.ceil(np.maximum(2.0 * (long_ - short), 0.0) / (1.5 * short) - 1e-9).astype(np.int64)
        gap = np.where(count > 1, 2.0 * (long_ - short) / np.maximum(count - 1, 1), 0.0)
        radius = np.sqrt(short * short + 0.25 * gap * gap)
        which = np.repeat(np.arange(len(self)), count)
        index = np.arange(len(which)) - np.repeat(np.cumsum(count) - count, count)  # 0..c-1 in each
        offset = (index - 0.5 * (count[which] - 1)) * gap[which]
        heading = self.headings[which] + np.where(along[which], 0.0, 0.5 * np.pi)
        direction = np.column_stack([np.cos(heading), np.sin(heading)])
        return Tracks(
            time=self.time,
            ids=self.ids[which],
            positions=self.positions[which] + offset[:, None] * direction,
            velocities=self.velocities[which],
            sizes=radius[which],
            position_var=self.position_var[which],
            velocity_var=self.velocity_var[which],
            position_velocity_cov=self.position_velocity_cov[which],
            age=self.age[which],
            last_seen=self.last_seen[which],
        )

    @staticmethod
    def empty(time: float = 0.0) -> Tracks:
        z2, z1 = np.zeros((0, 2)), np.zeros(0)
        return Tracks(time, np.zeros(0, dtype=np.int64), z2, z2, z1, z2, z2, z2, z1, z1)
