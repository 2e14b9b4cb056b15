"""The robot's 2D laser: `mj_multiRay` plus closed-form static cylinders, on a 1 mm grid."""

from __future__ import annotations

import mujoco
import numpy as np

from dynabarn.determinism import (
    LASER_RESOLUTION,
    snap_array,
)
from dynabarn.mjcf import ROBOT_PREFIX, STATIC_FIELD_BODY
from dynabarn.robot import JACKAL, LASER_GEOM_GROUPS, JackalParams
from dynabarn.worlds.ray_cast import circle_ranges


class Laser:
    """The UST-10 scan by `mj_multiRay` from the laser site, buffers reused every tick.

    A world's static cylinders (a BARN grid: hundreds of them) live in one body that
    `mj_multiRay` leaves out (its cost grows with every geom, about 7 us per cylinder per
    scan); the scan of those is computed here in closed form, each cylinder tested only
    against the few beams inside its angular extent. Both are exact; a test checks the sum
    against `mj_multiRay` over everything.
    """

    def __init__(
        self, model: mujoco.MjModel, params: JackalParams = JACKAL, static_cylinders: np.ndarray | None = None
    ) -> None:
        self.params = params
        self.site = model.site(f"{ROBOT_PREFIX}laser").id
        self.robot_body = model.body(f"{ROBOT_PREFIX}base_link").id
        self.angles = params.laser_angles()
        n = len(self.angles)
        self.n = n
        self._vec = np.zeros(3 * n)
        self._geomid = np.zeros(n, dtype=np.int32)
        self._dist = np.zeros(n)
        self._noise = np.zeros(n)
        self.static = np.zeros((0, 3)) if static_cylinders is None else np.asarray(static_cylinders).reshape(-1, 3)
        # The robot's geoms are in groups the laser mask leaves out, so the one excluded
        # body can be the static field's. (World files written before the field had its own
        # body keep their cylinders in the world body: mj_multiRay then casts them all.)
        self._exclude = self.robot_body
        if len(self.static):
            try:
                self._exclude = model.body(STATIC_FIELD_BODY).id
            except KeyError:
                self.static = np.zeros((0, 3))
        self._step = (self.angles[-1] - self.angles[0]) / (n - 1)

    def cast(self, model: mujoco.MjModel, data: mujoco.MjData, yaw: float) -> np.ndarray:
        """Noise-free ranges (n,) [m] for the current kinematics; no return reads range_max."""
        a = self.angles + yaw
        self._vec[0::3] = np.cos(a)
        self._vec[1::3] = np.sin(a)
        origin = data.site_xpos[self.site]
        mujoco.mj_multiRay(
            model,
            data,
            origin,
            self._vec,
            LASER_GEOM_GROUPS,
            1,
            self._exclude,
            self._geomid,
            self._dist,
            None,
            self.n,
            self.params.laser_range_max,
        )
        ranges = self._dist.copy()
        ranges[self._geomid < 0] = self.params.laser_range_max
        if len(self.static):
            static = self._cast_static(origin[0], origin[1], yaw)
            # mj_multiRay did not see the static field: a geom it hit behind a static
            # cylinder is hidden (the beam ends on the cylinder, which has no geom id here).
            self._geomid[static < ranges] = -1
            np.minimum(ranges, static, out=ranges)
        return ranges

    @property
    def geom_ids(self) -> np.ndarray:
        """(n,) the geom each beam of the last `cast` ended on (-1: none, or a static cylinder)."""
        return self._geomid

    def _cast_static(self, ox: float, oy: float, yaw: float) -> np.ndarray:
        """Ranges (n,) to the static cylinders (range_max where none is hit)."""
        return circle_ranges(ox, oy, yaw, self.angles, self.static, self.params.laser_range_max)

    def scan(self, model: mujoco.MjModel, data: mujoco.MjData, yaw: float, rng: np.random.Generator) -> np.ndarray:
        return self.noisy(self.cast(model, data, yaw), rng)

    def noisy(self, ranges: np.ndarray, rng: np.random.Generator | list[np.random.Generator]) -> np.ndarray:
        """Noise-free ranges (changed in place) -> the scan: Gaussian noise, clipped, 1 mm grid.
        Many worlds' at once: ranges (W, n) and one generator per row (each draws its own)."""
        # Each generator's standard normals, then scaled: the bits of g.normal(0, std, n)
        # (which draws the same normals and computes 0 + std * z), without its temporaries.
        if ranges.ndim == 1:  # one episode's scan, every tick: no rows to pair with generators
            noise = self._noise
            rng.standard_normal(out=noise)
        else:
            noise = np.empty(ranges.shape)
            for row, g in zip(noise, rng, strict=True):
                g.standard_normal(out=row)
        noise *= self.params.laser_noise_std
        ranges += noise
        # np.clip's bits without its Python wrapper (a per-tick cost of the runner's)
        np.maximum(ranges, self.params.laser_range_min, out=ranges)
        np.minimum(ranges, self.params.laser_range_max, out=ranges)
        # Whole millimetres, as the UST-10 reports: also what keeps last-bit differences of
        # the ray directions (numpy's sin and cos differ between CPUs) out of the planner.
        return snap_array(ranges, LASER_RESOLUTION, out=ranges)
