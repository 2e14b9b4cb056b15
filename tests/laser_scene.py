"""A laser scene for the trackers' known-answer tests: moving shapes (mocap bodies: boxes,
capsules, cylinders) and standing cylinders of the known map, built with `mujoco.MjSpec`
and scanned by MuJoCo's own ray casting from the Jackal's laser, with its noise."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from dynabarn.perception.detect import ObstacleDetector
from dynabarn.perception.shaped_tracker import ShapeTracker
from dynabarn.perception.tracker import ObstacleTracker
from dynabarn.robot import JACKAL

ANGLES = JACKAL.laser_angles()
LASER_Z = 0.3


class Scene:
    """Moving shapes (mocap bodies) and standing cylinders, scanned from a robot pose."""

    def __init__(self, moving: list[dict], standing: np.ndarray | None = None) -> None:
        spec = mujoco.MjSpec()
        for i, shape in enumerate(moving):
            yaw = shape.get("yaw", 0.0)
            body = spec.worldbody.add_body(name=f"moving{i}", pos=[0, 0, 0], mocap=True)
            turn = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
            if shape["kind"] == "box":
                body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[*shape["half"], 0.5], pos=[0, 0, 0.5], quat=turn)
            elif shape["kind"] == "capsule":  # lying along its yaw, axis at height r
                lie = np.zeros(4)
                mujoco.mju_mulQuat(
                    lie, np.array(turn), np.array([math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0])
                )
                r = shape["radius"]
                body.add_geom(
                    type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[r, shape["half_length"], 0], pos=[0, 0, r], quat=lie
                )
            else:
                body.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[shape["radius"], 0.5, 0], pos=[0, 0, 0.5])
        self.standing = np.zeros((0, 3)) if standing is None else np.asarray(standing, dtype=float)
        for x, y, r in self.standing:
            spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[r, 0.5, 0], pos=[x, y, 0.5])
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self.rng = np.random.default_rng(57)

    def scan(self, positions: np.ndarray, pose: np.ndarray) -> np.ndarray:
        self.data.mocap_pos[:, :2] = positions
        self.data.mocap_pos[:, 2] = 0.0
        mujoco.mj_kinematics(self.model, self.data)
        origin = [pose[0] + JACKAL.laser_x * math.cos(pose[2]), pose[1] + JACKAL.laser_x * math.sin(pose[2]), LASER_Z]
        a = ANGLES + pose[2]
        vec = np.column_stack([np.cos(a), np.sin(a), np.zeros(len(a))]).ravel()
        geom, dist = np.zeros(len(a), np.int32), np.zeros(len(a))
        mujoco.mj_multiRay(self.model, self.data, np.array(origin), vec, None, 1, -1, geom, dist, None, len(a), 30.0)
        ranges = np.where(geom < 0, 30.0, dist) + self.rng.normal(0.0, JACKAL.laser_noise_std, len(a))
        return np.round(np.minimum(ranges, 30.0), 3)

    def tracker(self, kind: type = ShapeTracker) -> ObstacleTracker:
        cfg = kind.Config(kind=kind.name)  # each tracker's own configuration
        detector = ObstacleDetector(
            cfg.detector,
            walls=np.zeros((0, 4)),
            static_obstacles=self.standing,
            laser_angles=ANGLES,
            laser_offset=np.array([JACKAL.laser_x, 0.0]),
            range_max=30.0,
        )
        return kind(cfg, detector)


def pose_looking_at(target: np.ndarray, bearing: float, distance: float) -> np.ndarray:
    """A robot pose `distance` from `target` at `bearing` from it, facing it."""
    x, y = target[0] + distance * math.cos(bearing), target[1] + distance * math.sin(bearing)
    return np.array([x, y, bearing + math.pi])
