"""The Clearpath Jackal: its numbers, its laser geometry and its frames, without MuJoCo.

Planners, behaviours and everything else that only needs the robot's numbers import this
module; its MJCF model, built from these numbers with MjSpec, is `dynabarn.robot_mjcf`
(the committed `assets/jackal/jackal.xml` is its output). `assets/jackal/README.md` gives
the source of every number below.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dynabarn.provenance import ASSETS_DIR

PHYSICS_TIMESTEP = 0.005
"""[s] The physics step the robot and every world are written with (measured: at 0.01 s and
above a 2 m/s obstacle passes through the robot); `SimConfig.dt` may run another."""

JACKAL_XML = ASSETS_DIR / "jackal" / "jackal.xml"
"""The committed robot file (in a wheel: the copy under `dynabarn/data/assets`)."""
JACKAL_REL = Path("assets") / "jackal" / "jackal.xml"
"""Where a world set's root keeps the robot: world files name it relative to their folder."""


class GeomGroup(enum.IntEnum):
    """Geom groups shared by the world compiler, the laser and the viewers."""

    STATIC = 0
    """Floor and walls."""
    OBSTACLE = 1
    """Moving obstacles (mocap bodies)."""
    ROBOT_VISUAL = 2
    """The Jackal's visual geoms (no contacts)."""
    ROBOT_COLLISION = 3
    """The Jackal's collision box."""
    MARKER = 4
    """Goal and other markers (no contacts, invisible to the laser)."""


LASER_GEOM_GROUPS = np.array([1, 1, 0, 0, 0, 0], dtype=np.uint8)
"""mj_multiRay geomgroup mask: the laser sees static geoms and obstacles only."""


@dataclass(frozen=True, slots=True)
class JackalParams:
    """Every physical number of the model (sources in assets/jackal/README.md)."""

    length: float = 0.508  # [m] Clearpath Jackal spec, overall L
    width: float = 0.430  # [m] overall W
    height: float = 0.250  # [m] overall H
    mass: float = 17.0  # [kg] Clearpath spec ("17 kg")
    wheel_radius: float = 0.098  # [m] Clearpath jackal_description (Menagerie uses 0.095)
    wheel_width: float = 0.04  # [m] visual only
    wheel_x: float = 0.131  # [m] wheel base half-length (Menagerie jackal.xml)
    wheel_y: float = 0.187795  # [m] track half-width (Menagerie jackal.xml)
    v_min: float = -0.5  # [m/s] paper's command space
    v_max: float = 2.0  # [m/s] Jackal top speed
    w_max: float = 3.14  # [rad/s] paper's command space
    velocity_gain: float = 50.0  # [1/s] actuator bandwidth: tracks a step in ~0.1 s
    laser_beams: int = 720  # Hokuyo UST-10 as on the BARN Jackal
    laser_fov: float = 2.35619  # [rad] half field of view (+-135 deg)
    laser_range_min: float = 0.1  # [m]
    laser_range_max: float = 30.0  # [m]
    laser_noise_std: float = 0.001  # [m] Gaussian noise of the BARN Jackal's laser plugin
    laser_x: float = 0.12  # [m] front mount, ahead of the base centre
    laser_z: float = 0.30  # [m] above the ground, just over the top plate

    @property
    def yaw_inertia(self) -> float:
        """[kg m^2] of a uniform box of the footprint about z."""
        return self.mass * (self.length**2 + self.width**2) / 12.0

    @property
    def footprint_radius(self) -> float:
        """[m] circumscribed radius of the footprint (for planners' inflation)."""
        return math.hypot(self.length / 2, self.width / 2)

    def laser_angles(self) -> np.ndarray:
        """(laser_beams,) beam angles in the robot frame [rad], right to left."""
        return np.linspace(-self.laser_fov, self.laser_fov, self.laser_beams)


JACKAL = JackalParams()


def to_robot_frame(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """World points (n, 2) into the robot frame of pose (x, y, yaw)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    if len(points) == 1:  # one point (a goal): the same products and sums on Python floats
        dx, dy = float(points[0][0]) - float(pose[0]), float(points[0][1]) - float(pose[1])
        return np.array([[c * dx + s * dy, -s * dx + c * dy]])
    d = np.asarray(points) - pose[:2]
    out = np.empty((len(d), 2))
    # The same products and sums as two column expressions, written into one array.
    np.add(c * d[:, 0], s * d[:, 1], out=out[:, 0])
    np.add(-s * d[:, 0], c * d[:, 1], out=out[:, 1])
    return out


def mounted_pose(pose: np.ndarray, offset) -> np.ndarray:
    """Pose (x, y, yaw) of a part mounted at `offset` (x, y) in the robot frame, for robot
    poses (3,) or (n, 3): e.g. the laser, `laser_x` ahead of the centre."""
    pose = np.asarray(pose, dtype=np.float64)
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    ox, oy = float(offset[0]), float(offset[1])
    if pose.ndim == 1:  # one pose (every control tick): the same products and sums, no stacking
        return np.array([pose[0] + c * ox - s * oy, pose[1] + s * ox + c * oy, pose[2]])
    return np.stack([pose[..., 0] + c * ox - s * oy, pose[..., 1] + s * ox + c * oy, pose[..., 2]], axis=-1)
