"""A compiled world ready for episodes: model, data, laser, obstacle facts, clearance."""

from __future__ import annotations

import copy
import hashlib
from collections import OrderedDict
from pathlib import Path

import mujoco
import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.interfaces.observation import EpisodeInfo
from dynabarn.metrics import (
    footprint_clearance,
    shape_clearance,
)
from dynabarn.mjcf import ROBOT_PREFIX, load_model, open_world
from dynabarn.protocol import EvalProtocol
from dynabarn.robot import JACKAL, JackalParams
from dynabarn.sim.behaviors import check_behaviors
from dynabarn.sim.laser import Laser
from dynabarn.sim.physics_period import PhysicsPeriod
from dynabarn.sim_config import SimConfig
from dynabarn.world_file import world_bytes
from dynabarn.worlds.fingerprint import world_fingerprint

CLEARANCE_CHUNK = 1000
"""Poses per batch of the clearance metric."""
COMPILED_CACHE = 64
"""Compiled worlds kept per process (many environments meeting the same worlds)."""
_compiled: OrderedDict[str, mujoco.MjModel] = OrderedDict()


def compiled_model(path: Path, data: bytes, key: str, root=None) -> mujoco.MjModel:
    """The runner's model of a world file's bytes (`key`: their sha256; `root`: their
    document, parsed and checked): compiled once per process, a copy each time (an episode
    sets its model's options), the same model either way."""
    if key not in _compiled:
        _compiled[key] = load_model(path, beam_sensors=False, data=data, root=root)
        while len(_compiled) > COMPILED_CACHE:
            _compiled.popitem(last=False)
    _compiled.move_to_end(key)
    return copy.copy(_compiled[key])


class Simulation:
    """A compiled world ready for episodes: model, data, obstacle mapping and buffers."""

    def __init__(self, world_path: Path | str, *, config: SimConfig = SimConfig()) -> None:
        self.world_path = Path(world_path)
        data = world_bytes(self.world_path)  # read once: the hash covers what is compiled
        root, self.world = open_world(self.world_path, data)  # parsed and checked once
        check_behaviors(self.world.obstacles)
        self.world_sha256 = hashlib.sha256(data).hexdigest()
        self.world_fingerprint = world_fingerprint(self.world)
        self.world_xml = data
        self.config = config
        # The runner casts its own scans with mj_multiRay, so it compiles the world with the
        # Jackal's variant without the 720 beam sites and rangefinders (same geometry).
        self.model = compiled_model(self.world_path, data, self.world_sha256, root)
        self.model.opt.timestep = config.dt
        self.data = mujoco.MjData(self.model)
        try:
            mocap_ids = [self.model.body(o.name).mocapid[0] for o in self.world.obstacles]
            self.model.body(f"{ROBOT_PREFIX}base_link")
        except KeyError as exc:
            raise DynabarnError(f"{self.world_path}: the model has no body {exc}") from None
        if mocap_ids != list(range(len(mocap_ids))):
            raise DynabarnError(f"{self.world_path}: obstacle bodies are not the first mocap bodies in order")
        self.physics = PhysicsPeriod(self.model, self.data, config.steps_per_tick)
        self.static_cylinders = np.array(self.world.layout.cylinders, dtype=np.float64).reshape(-1, 3)
        self.laser = Laser(self.model, static_cylinders=self.static_cylinders)
        obstacles = self.world.obstacles
        self.radii = np.array([o.radius for o in obstacles])
        """Rounding radius of every obstacle's footprint (its radius, for a cylinder)."""
        self.bounding_radii = np.array([o.bounding_radius for o in obstacles])
        self.yaws = np.array([o.yaw for o in obstacles])
        self.core_half_extents = np.array([o.half_extents for o in obstacles], dtype=np.float64).reshape(-1, 2)
        self.shaped = bool(np.any(self.core_half_extents))
        """Some obstacle is a box or a capsule: clearance uses the general shape distance."""
        self.goal = np.array(self.world.layout.goal, dtype=np.float64)
        self.walls = np.array(
            [[w.centre[0], w.centre[1], w.size[0], w.size[1]] for w in self.world.layout.walls], dtype=np.float64
        ).reshape(-1, 4)
        self.robot_geoms = {i for i in range(self.model.ngeom) if self.model.geom_bodyid[i] == self.laser.robot_body}
        mocap = self.model.body_mocapid[self.model.geom_bodyid]
        self.obstacle_of_geom = np.where(mocap < len(obstacles), mocap, -1)
        """(ngeom,) the obstacle each geom belongs to, -1 for the rest (the laser's hits -> obstacles)."""

    def fork(self) -> Simulation:
        """Another simulation of the same compiled world, for another episode at the same
        time: the world, its model and every fact read from them shared (nothing changes them
        after compiling), its own data and the laser's and the physics' buffers. A fraction
        of a new `Simulation`'s cost: many environments meeting the same worlds fork one."""
        other = copy.copy(self)
        other.data = mujoco.MjData(self.model)
        other.laser = Laser(self.model, static_cylinders=self.static_cylinders)
        other.physics = PhysicsPeriod(self.model, other.data, self.config.steps_per_tick)
        return other

    def reset(self, spawn: tuple[float, float, float]) -> None:
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:3] = spawn

    def set_obstacles(self, xy: np.ndarray) -> None:
        self.data.mocap_pos[: len(xy), :2] = xy

    def clearance(self, poses: np.ndarray, obstacle_xy: np.ndarray, *, static: bool = False) -> np.ndarray:
        """Footprint clearance (T,) at poses (T, 3) to the moving obstacles at centres
        (T, n, 2), and to the static cylinders too with `static`; in chunks of
        CLEARANCE_CHUNK poses, so a long episode's temporaries stay a few MB."""
        half = (JACKAL.length / 2, JACKAL.width / 2)
        cylinders = self.static_cylinders if static else np.zeros((0, 3))
        out = np.empty(len(poses))
        for i in range(0, len(poses), CLEARANCE_CHUNK):
            part, xy = poses[i : i + CLEARANCE_CHUNK], obstacle_xy[i : i + CLEARANCE_CHUNK]
            if self.shaped:
                c = shape_clearance(part, xy, self.yaws, self.core_half_extents, self.radii, half)
            else:
                c = footprint_clearance(part, xy, self.radii, half)
            if len(cylinders):
                at = np.broadcast_to(cylinders[:, :2], (len(part), len(cylinders), 2))
                c = np.minimum(c, footprint_clearance(part, at, cylinders[:, 2], half))
            out[i : i + CLEARANCE_CHUNK] = c
        return out

    def episode_info(self, protocol: EvalProtocol, seed: int, params: JackalParams = JACKAL) -> EpisodeInfo:
        return EpisodeInfo(
            laser_angles=self.laser.angles.copy(),
            laser_offset=np.array([params.laser_x, 0.0]),
            laser_range=(params.laser_range_min, params.laser_range_max),
            control_period=self.config.control_period,
            v_limits=(params.v_min, params.v_max),
            w_max=params.w_max,
            accel_limits=(self.config.max_linear_accel, self.config.max_angular_accel),
            footprint=(params.length, params.width),
            walls=self.walls.copy(),
            goal=self.goal.copy(),
            goal_tolerance=protocol.goal_tolerance,
            seed=seed,
            static_obstacles=self.static_cylinders.copy(),
            world_fingerprint=self.world_fingerprint,
        )
