"""The episode loop: a world, a planner and a protocol in MuJoCo.

Per control tick (default 10 Hz): set the obstacles for the current time, cast the
720-beam scan with `mj_multiRay`, ask the planner for (v, w), limit it, and then run the
physics steps of the period (default dt = 0.005 s, 20 steps). Obstacle positions for all
steps of the period come from one vectorised schedule evaluation; inside the physics loop
each step only copies a row into `mocap_pos`, steps MuJoCo and checks contacts, the goal
and the clock. Nothing is allocated per physics step.

Trials differ only by seed: the seed draws the obstacles' clock offset in [0, 5) s (in
Gazebo, trials differed by when the robot started relative to the looping obstacles) and
the laser noise. Same world, planner, protocol and seed: same result on any machine.

Observers (`EpisodeObserver`) receive the start, every tick, the robot poses and the
result; the MCAP recorder is one. The loop knows nothing of recording.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import mujoco
import numpy as np

from dynabarn.determinism import (
    COMMAND_RESOLUTION,
    LASER_RESOLUTION,
    OBSTACLE_SPEED_RESOLUTION,
    RECORD_RESOLUTION,
    snap,
    snap_array,
)
from dynabarn.errors import DynabarnError
from dynabarn.metrics import (
    EpisodeResult,
    Outcome,
    compute_percentiles,
    footprint_clearance,
    footprint_clearance_at,
    mean_abs_jerk,
    path_length,
    shape_clearance,
    spl,
    stalled_time,
    sum_abs_change,
)
from dynabarn.mjcf import ROBOT_PREFIX, STATIC_FIELD_BODY, load_model, read_world
from dynabarn.planners.base import EndEpisode, EpisodeInfo, Observation, ObstacleState, Planner
from dynabarn.protocol import EvalProtocol, GoalRegion
from dynabarn.provenance import machine, portable_path, versions
from dynabarn.robot import JACKAL, LASER_GEOM_GROUPS, JackalParams
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import WorldSpec

MAX_CLOCK_OFFSET = 5.0
"""Trials start the obstacles' clocks at a seeded offset in [0, 5) s."""
CLEARANCE_CHUNK = 1000
"""Poses per batch of the clearance metric."""

# The `avoid` behaviour's social force (per unit mass), after Helbing & Molnar (1995).
AVOID_STRENGTH = 4.0
"""[m/s^2] sideways push at contact distance."""
AVOID_RANGE = 0.4
"""[m] decay length of the push."""
AVOID_ANISOTROPY = 0.35
"""Weight of a robot straight behind relative to one straight ahead (1)."""
AVOID_STIFFNESS = 0.5
"""[1/s^2] pull back onto the path ..."""
AVOID_DAMPING = 2 * math.sqrt(AVOID_STIFFNESS)
"""[1/s] ... critically damped."""
AVOID_MAX_SPEED = 1.5
"""[m/s] fastest sideways step."""
AVOID_MAX_OFFSET = 3.0
"""[m] furthest from the path."""
AVOID_BRAKE_BAND = 1.0
"""[m] beyond contact distance, over which an obstacle with the robot in its way slows to a stop."""


@dataclass(frozen=True, slots=True)
class SimConfig:
    """Settings of the episode loop.

    Attributes:
        dt: physics step [s] (<= 0.01: at 0.05 s a 2 m/s obstacle passes through the robot).
        control_rate: planner and scan rate [Hz]; the control period must be a whole
            number of physics steps.
        pose_rate: rate at which robot poses are handed to observers (and recorded) [Hz].
        max_linear_accel: |dv/dt| limit on the command [m/s^2] (jackal_control's
            diff-drive controller: linear.x.max_acceleration 20).
        max_angular_accel: |dw/dt| limit on the command [rad/s^2] (angular.z.max_acceleration 25).
    """

    dt: float = 0.005
    control_rate: float = 10.0
    pose_rate: float = 50.0
    max_linear_accel: float = 20.0
    max_angular_accel: float = 25.0

    def __post_init__(self) -> None:
        if not 0 < self.dt <= 0.01:
            raise DynabarnError(f"physics step dt must be in (0, 0.01] s, got {self.dt}")
        if self.control_rate <= 0 or self.pose_rate <= 0:
            raise DynabarnError("control and pose rates must be positive")
        k = 1.0 / (self.control_rate * self.dt)
        if abs(k - round(k)) > 1e-6 or round(k) < 1:
            raise DynabarnError(
                f"the control period 1/{self.control_rate} s must be a whole number of physics steps of {self.dt} s"
            )

    @property
    def steps_per_tick(self) -> int:
        return round(1.0 / (self.control_rate * self.dt))

    @property
    def control_period(self) -> float:
        return self.steps_per_tick * self.dt

    @property
    def pose_every(self) -> int:
        return max(1, round(1.0 / (self.pose_rate * self.dt)))


@dataclass(frozen=True, slots=True)
class EpisodeStart:
    """What observers learn when an episode starts."""

    world: WorldSpec
    world_path: Path
    world_sha256: str
    protocol: EvalProtocol
    planner: str
    planner_config: dict
    seed: int
    clock_offset: float
    config: SimConfig
    info: EpisodeInfo
    versions: dict


@dataclass(slots=True)
class Tick:
    """One control tick, as observers see it. Arrays are fresh (observers may keep them)."""

    time: float
    scan: np.ndarray  # (n_beams,)
    laser_pose: np.ndarray  # (3,) x, y, yaw of the laser in the world
    pose: np.ndarray  # (3,)
    velocity: np.ndarray  # (2,) measured v, w
    command: np.ndarray  # (2,) limited v, w sent to the robot
    raw_command: np.ndarray  # (2,) what the planner returned
    obstacles: np.ndarray  # (n_obstacles, 2)
    clearance: float
    distance_to_goal: float
    planner_ms: float
    debug: dict = field(default_factory=dict)


class EpisodeObserver(Protocol):
    def on_start(self, start: EpisodeStart) -> None: ...

    def on_tick(self, tick: Tick) -> None: ...

    def on_poses(self, times: np.ndarray, poses: np.ndarray) -> None: ...

    def on_end(self, result: EpisodeResult) -> None: ...


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
            np.minimum(ranges, self._cast_static(origin[0], origin[1], yaw), out=ranges)
        return ranges

    def _cast_static(self, ox: float, oy: float, yaw: float) -> np.ndarray:
        """Ranges (n,) to the static cylinders (range_max where none is hit)."""
        out = np.full(self.n, self.params.laser_range_max)
        d = self.static[:, :2] - (ox, oy)
        r = self.static[:, 2]
        dist = np.hypot(d[:, 0], d[:, 1])
        near = (dist - r < self.params.laser_range_max) & (dist > r)
        d, r, dist = d[near], r[near], dist[near]
        # Beams within each cylinder's angular extent [theta - alpha, theta + alpha].
        theta = np.arctan2(d[:, 1], d[:, 0]) - yaw
        theta = (theta + np.pi) % (2 * np.pi) - np.pi
        alpha = np.arcsin(r / dist)
        lo = np.maximum(np.ceil((theta - alpha - self.angles[0]) / self._step), 0).astype(np.int64)
        hi = np.minimum(np.floor((theta + alpha - self.angles[0]) / self._step), self.n - 1).astype(np.int64)
        counts = np.maximum(hi - lo + 1, 0)
        total = int(counts.sum())
        if total == 0:
            return out
        which = np.repeat(np.arange(len(counts)), counts)
        beam = lo[which] + np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        a = self.angles[beam] + yaw
        # Ray o + t u against the circle |p - c| = r: t = b - sqrt(b^2 - (|c - o|^2 - r^2)), b = u . (c - o).
        dc = d[which]
        b = np.cos(a) * dc[:, 0] + np.sin(a) * dc[:, 1]
        disc = b * b - (dist[which] ** 2 - r[which] ** 2)
        hit = disc >= 0
        t = b[hit] - np.sqrt(disc[hit])
        np.minimum.at(out, beam[hit], t)
        return out

    def scan(self, model: mujoco.MjModel, data: mujoco.MjData, yaw: float, rng: np.random.Generator) -> np.ndarray:
        ranges = self.cast(model, data, yaw)
        ranges += rng.normal(0.0, self.params.laser_noise_std, self.n)
        np.clip(ranges, self.params.laser_range_min, self.params.laser_range_max, out=ranges)
        # Whole millimetres, as the UST-10 reports: also what keeps last-bit differences of
        # the ray directions (numpy's sin and cos differ between CPUs) out of the planner.
        return snap_array(ranges, LASER_RESOLUTION, out=ranges)


class Simulation:
    """A compiled world ready for episodes: model, data, obstacle mapping and buffers."""

    def __init__(self, world_path: Path | str, *, config: SimConfig = SimConfig()) -> None:
        self.world_path = Path(world_path)
        self.world = read_world(self.world_path)
        self.world_sha256 = hashlib.sha256(self.world_path.read_bytes()).hexdigest()
        self.config = config
        # The runner casts its own scans with mj_multiRay, so it compiles the world with the
        # Jackal's variant without the 720 beam sites and rangefinders (same geometry).
        self.model = load_model(self.world_path, beam_sensors=False)
        self.model.opt.timestep = config.dt
        self.data = mujoco.MjData(self.model)
        mocap_ids = [self.model.body(o.name).mocapid[0] for o in self.world.obstacles]
        if mocap_ids != list(range(len(mocap_ids))):
            raise DynabarnError(f"{self.world_path}: obstacle bodies are not the first mocap bodies in order")
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
        )


def _goal_in_robot(pose: np.ndarray, goal: np.ndarray) -> np.ndarray:
    dx, dy = goal[0] - pose[0], goal[1] - pose[1]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([c * dx + s * dy, -s * dx + c * dy])


class Episode:
    """One episode's state, advanced one control period at a time.

    `observe()` places the obstacles for the current time and casts the scan; `apply(v, w)`
    limits the command and runs the physics steps of one control period, checking contacts,
    the goal and the clock after every step. `run_episode` and the Gymnasium environment
    both drive episodes through this class.

    Args:
        sim: the compiled world.
        protocol: the rules.
        seed: the trial seed (obstacle clock offset in [0, 5) s, laser noise).
        privileged: include the true obstacle states in observations.
    """

    def __init__(self, sim: Simulation, protocol: EvalProtocol, *, seed: int = 0, privileged: bool = False) -> None:
        self.sim = sim
        self.protocol = protocol
        self.seed = seed
        self.privileged = privileged
        config = sim.config
        self.rng = np.random.default_rng(np.random.SeedSequence(seed))
        self.clock_offset = float(self.rng.uniform(0.0, MAX_CLOCK_OFFSET))
        self.player = SchedulePlayer(sim.world, clock_offset=self.clock_offset)
        self.info = sim.episode_info(protocol, seed)
        self.dt = config.dt
        self.k = config.steps_per_tick
        self.period = config.control_period
        # Longest possible episode: the clock may start as late as `limit`, then run `limit`.
        max_steps = math.ceil(2 * protocol.time_limit / self.dt) + 2 * self.k
        self.poses = np.zeros((max_steps + 1, 3))  # robot pose after every physics step
        n_ticks_max = max_steps // self.k + 2
        self.tick_v = np.zeros(n_ticks_max)
        self.tick_w = np.zeros(n_ticks_max)
        self.tick_w_cmd = np.zeros(n_ticks_max)
        self.planner_ms = np.zeros(n_ticks_max)
        self._step_offsets = np.arange(self.k) * self.dt
        sim.reset(protocol.spawn)
        self.poses[0] = protocol.spawn
        self.outcome: Outcome | None = None
        self.reason = ""
        self.t_start: float | None = 0.0 if protocol.timer_start_distance == 0.0 else None
        self.step = 0
        self.n_ticks = 0
        self.prev_cmd = np.zeros(2)
        self.raw_command = (0.0, 0.0)
        self.wall_t0 = time.perf_counter()
        self._batch_xy = self._batch_vel = None
        # Reactive obstacles run on their own clocks (a yielding one pauses its schedule);
        # scripted-only worlds keep the exact global clock.
        obstacles = sim.world.obstacles
        self.reactive = any(o.behavior != "scripted" for o in obstacles)
        if self.reactive:
            n = len(obstacles)
            self._yields = np.array([o.behavior == "yield" for o in obstacles])
            self._yield_distance = np.array([o.yield_distance for o in obstacles])
            self._avoids = np.array([o.behavior == "avoid" for o in obstacles])
            self._any_avoid = bool(self._avoids.any())
            self._avoid_distance = np.array([o.avoid_distance for o in obstacles])
            self._reach = sim.bounding_radii + JACKAL.footprint_radius  # centre distance at contact
            self.obstacle_clock = np.zeros(n)
            self.lateral = np.zeros(n)  # `avoid`: sideways offset from the path [m] ...
            self.lateral_speed = np.zeros(n)  # ... and its rate [m/s]
            self._normal = np.zeros((n, 2))  # last left normal of each path (kept when it stops)
            self.obstacle_log = np.zeros((max_steps + 1, n, 2))

    @property
    def time(self) -> float:
        return self.step * self.dt

    def observe(self) -> Observation:
        """Place the obstacles for now, cast the scan, and return what a planner sees."""
        sim = self.sim
        model, data = sim.model, sim.data
        t = self.time
        # All obstacle positions of this control period in one vectorised call.
        if self.reactive:
            self._batch_xy, self._batch_vel = self._reactive_batch()
        else:
            self._batch_xy, self._batch_vel = self.player.positions_at(t + self._step_offsets)
        sim.set_obstacles(self._batch_xy[0])
        mujoco.mj_kinematics(model, data)
        qpos, qvel = data.qpos, data.qvel
        pose = qpos[:3].copy()
        c, s = math.cos(pose[2]), math.sin(pose[2])
        velocity = np.array([c * qvel[0] + s * qvel[1], qvel[2]])
        scan = sim.laser.scan(model, data, pose[2], self.rng)
        privileged = None
        if self.privileged:
            privileged = ObstacleState(
                positions=self._batch_xy[0].copy(),
                velocities=self._batch_vel[0].copy(),
                radii=sim.bounding_radii.copy(),
                predict=_constant_velocity(t, self._batch_xy[0], self._batch_vel[0])
                if self.reactive
                else _predictor(self.player),
            )
        self._obs = Observation(
            time=t,
            scan=scan,
            pose=pose,
            velocity=velocity,
            goal_in_robot=_goal_in_robot(pose, sim.goal),
            goal_in_world=sim.goal.copy(),
            obstacles=privileged,
        )
        return self._obs

    def _reactive_batch(self) -> tuple[np.ndarray, np.ndarray]:
        """This period's positions of obstacles on their own clocks, all obstacles at once.

        `yield`: an obstacle whose way ahead holds the robot within its yield distance
        holds still for the period. `avoid` (social force, Helbing & Molnar 1995): within
        `avoid_distance` the robot pushes the obstacle sideways off its path with
        AVOID_STRENGTH * exp((reach - d) / AVOID_RANGE), weighted towards what lies ahead
        (anisotropy AVOID_ANISOTROPY), while a damped spring pulls it back onto the path;
        if the robot is in its way within AVOID_BRAKE_BAND it also slows its schedule.
        The offset's rate is updated once per control period and held within it.
        """
        pos, vel = self.player.positions_at_local(self.obstacle_clock[None])
        pos, vel = pos[0], vel[0]
        normal = self._normal = self._step_normals(vel[None])[0]
        actual = pos + self.lateral[:, None] * normal
        rel = self.sim.data.qpos[:2] - actual  # (n, 2) robot relative to each obstacle
        dist = np.hypot(rel[:, 0], rel[:, 1])
        ahead = (rel * vel).sum(axis=1) > 0.0
        rate = np.where(self._yields & ahead & (dist < self._yield_distance), 0.0, 1.0)
        if self._any_avoid:
            rate = np.minimum(rate, self._avoid_step(rel, dist, vel, normal, ahead))
        offsets = self._step_offsets[:, None]
        local = self.obstacle_clock[None, :] + offsets * rate[None, :]
        self.obstacle_clock = self.obstacle_clock + rate * self.period
        xy, v = self.player.positions_at_local(local)
        v = v * rate[None, :, None]
        if self._any_avoid:
            normals = self._step_normals(v)
            lateral = self.lateral[None, :] + offsets * self.lateral_speed[None, :]
            xy = xy + lateral[..., None] * normals
            v = v + self.lateral_speed[None, :, None] * normals
            self.lateral = self.lateral + self.lateral_speed * self.period
        return xy, v

    def _step_normals(self, v: np.ndarray) -> np.ndarray:
        """Left normals (k, n, 2) of the paths at the period's steps (last known when stopped)."""
        speed = np.hypot(v[..., 0], v[..., 1])[..., None]
        nrm = np.stack([-v[..., 1], v[..., 0]], axis=-1) / np.where(speed > 1e-9, speed, 1.0)
        return np.where(speed > 1e-9, nrm, self._normal[None])

    def _avoid_step(
        self, rel: np.ndarray, dist: np.ndarray, vel: np.ndarray, normal: np.ndarray, ahead: np.ndarray
    ) -> np.ndarray:
        """Update the `avoid` obstacles' sideways motion; their schedule rates (n,)."""
        speed = np.hypot(vel[:, 0], vel[:, 1])
        along = (rel * vel).sum(axis=1) / np.where(speed > 1e-9, speed, 1.0)
        side = (rel * normal).sum(axis=1)  # > 0: the robot is on the path's left
        reach = self._reach
        near = self._avoids & (dist < self._avoid_distance)
        cos_phi = np.where(dist > 1e-9, along / np.maximum(dist, 1e-9), 1.0)
        weight = AVOID_ANISOTROPY + (1 - AVOID_ANISOTROPY) * (1 + cos_phi) / 2
        push = AVOID_STRENGTH * np.exp((reach - dist) / AVOID_RANGE) * weight
        away = np.where(side > 0, -1.0, 1.0)  # step away from the side the robot is on; dead ahead, step left
        force = np.where(near, away * push, 0.0)
        force -= AVOID_STIFFNESS * self.lateral + AVOID_DAMPING * self.lateral_speed  # back onto the path
        speed_lat = np.clip(self.lateral_speed + force * self.period, -AVOID_MAX_SPEED, AVOID_MAX_SPEED)
        speed_lat = np.where(self._avoids, speed_lat, 0.0)
        # Never further than AVOID_MAX_OFFSET from the path.
        limit = (AVOID_MAX_OFFSET - np.abs(self.lateral)) / self.period
        self.lateral_speed = snap_array(
            np.where(np.sign(speed_lat) == np.sign(self.lateral), np.clip(speed_lat, -limit, limit), speed_lat),
            OBSTACLE_SPEED_RESOLUTION,
        )
        in_way = near & ahead & (np.abs(side) < reach)
        brake = np.clip((dist - reach) / AVOID_BRAKE_BAND, 0.0, 1.0)
        return np.where(in_way, brake, 1.0)

    def end(self, outcome: Outcome, reason: str) -> None:
        self.outcome, self.reason = outcome, reason

    def apply(self, raw_v: float, raw_w: float) -> Outcome | None:
        """Limit the command, then run one control period of physics; the outcome if it ended."""
        if not (math.isfinite(raw_v) and math.isfinite(raw_w)):
            self.end(Outcome.ERROR, f"planner returned a non-finite command ({raw_v}, {raw_w})")
            return self.outcome
        sim, cfg, p = self.sim, self.sim.config, JACKAL
        data, model = sim.data, sim.model
        # On a fixed grid: a planner's last-bit differences between machines stop here.
        raw_v, raw_w = snap(raw_v, COMMAND_RESOLUTION), snap(raw_w, COMMAND_RESOLUTION)
        self.raw_command = (raw_v, raw_w)
        v = min(max(raw_v, p.v_min), p.v_max)
        w = min(max(raw_w, -p.w_max), p.w_max)
        dv, dw = cfg.max_linear_accel * self.period, cfg.max_angular_accel * self.period
        prev = self.prev_cmd
        v = min(max(v, prev[0] - dv), prev[0] + dv)
        w = min(max(w, prev[1] - dw), prev[1] + dw)
        self.prev_cmd = np.array([v, w])
        data.ctrl[0], data.ctrl[1], data.ctrl[2] = v, 0.0, w
        n = self.n_ticks
        self.tick_v[n], self.tick_w[n], self.tick_w_cmd[n] = self._obs.velocity[0], self._obs.velocity[1], w
        self.n_ticks += 1

        protocol = self.protocol
        dt, poses, batch_xy = self.dt, self.poses, self._batch_xy
        robot_qpos = data.qpos[:3]  # views reused every physics step
        mocap_xy = data.mocap_pos[: sim.radii.size, :2]
        gx, gy = float(sim.goal[0]), float(sim.goal[1])
        sx, sy = protocol.spawn[0], protocol.spawn[1]
        start_r2 = protocol.timer_start_distance**2
        tol = protocol.goal_tolerance
        tol2 = tol * tol
        goal_disc = protocol.goal_region == GoalRegion.DISC
        limit = protocol.time_limit
        step, t_start = self.step, self.t_start
        outcome = None
        if self.reactive:  # what the obstacles really did, for the clearance metric
            n_log = min(self.k, len(self.obstacle_log) - step)
            self.obstacle_log[step : step + n_log] = batch_xy[:n_log]
        for j in range(self.k):
            mocap_xy[...] = batch_xy[j]
            mujoco.mj_step(model, data)
            step += 1
            poses[step] = robot_qpos
            x, y = robot_qpos[0], robot_qpos[1]
            if data.ncon:
                self.reason = f"hit {_contact_partner(model, data, sim.robot_geoms)}"
                outcome = Outcome.COLLISION
                break
            ts = step * dt
            if t_start is None and (x - sx) ** 2 + (y - sy) ** 2 >= start_r2:
                t_start = ts
            dx, dy = x - gx, y - gy
            if (dx * dx + dy * dy < tol2) if goal_disc else (abs(dx) < tol and abs(dy) < tol):
                outcome, self.reason = Outcome.SUCCESS, "reached the goal"
                break
            if ts - (t_start if t_start is not None else 0.0) >= limit:
                outcome, self.reason = Outcome.TIMEOUT, f"time limit {limit:g} s"
                break
        self.step, self.t_start, self.outcome = step, t_start, outcome
        return outcome

    def tick_record(self, debug: dict) -> Tick:
        """The last observation and command (as received, on its grid), for observers."""
        obs, sim = self._obs, self.sim
        laser_xy = sim.data.site_xpos[sim.laser.site]
        pose = obs.pose
        return Tick(
            time=obs.time,
            scan=obs.scan,
            laser_pose=np.array([laser_xy[0], laser_xy[1], pose[2]]),
            pose=pose,
            velocity=obs.velocity,
            command=self.prev_cmd.copy(),
            raw_command=np.array(self.raw_command, dtype=np.float64),
            obstacles=self._batch_xy[0].copy(),
            clearance=snap(
                float(sim.clearance(pose[None], self._batch_xy[:1])[0])
                if sim.shaped
                else footprint_clearance_at(
                    pose[0], pose[1], pose[2], self._batch_xy[0], sim.radii, (JACKAL.length / 2, JACKAL.width / 2)
                ),
                RECORD_RESOLUTION,
            ),
            distance_to_goal=math.hypot(sim.goal[0] - pose[0], sim.goal[1] - pose[1]),
            planner_ms=float(self.planner_ms[self.n_ticks - 1]) if self.n_ticks else 0.0,
            debug=debug,
        )

    def poses_between(self, first: int) -> tuple[np.ndarray, np.ndarray]:
        """Times and poses at the pose rate after physics step `first` up to now (the last
        pose always included once the episode has ended)."""
        every = self.sim.config.pose_every
        first_idx = 0 if first == 0 else first + every - first % every
        idx = np.arange(first_idx, self.step + 1, every)
        if self.step % every and self.outcome is not None:
            idx = np.append(idx, self.step)
        return idx * self.dt, self.poses[idx].copy()

    def result(self, start: EpisodeStart) -> EpisodeResult:
        return _finish(self, start)


def run_episode(
    world: Path | str | Simulation,
    planner: Planner,
    protocol: EvalProtocol,
    *,
    seed: int = 0,
    config: SimConfig = SimConfig(),
    observers: Sequence[EpisodeObserver] = (),
    planner_name: str | None = None,
) -> EpisodeResult:
    """Run one episode and return its result.

    A planner that raises or returns a non-finite command ends the episode with outcome
    `error` and the reason. Ctrl-C ends it the same way (reason "interrupted"), lets the
    observers finish (the recording is closed and complete), then re-raises.
    """
    sim = world if isinstance(world, Simulation) else Simulation(world, config=config)
    episode = Episode(sim, protocol, seed=seed, privileged=planner.privileged)
    start = EpisodeStart(
        world=sim.world,
        world_path=sim.world_path,
        world_sha256=sim.world_sha256,
        protocol=protocol,
        planner=planner_name or getattr(planner, "name", type(planner).__name__),
        planner_config=planner.config(),
        seed=seed,
        clock_offset=episode.clock_offset,
        config=sim.config,
        info=episode.info,
        versions=versions() | planner.versions(),
    )
    for obs_ in observers:
        obs_.on_start(start)
    try:
        planner.reset(episode.info)
        while episode.outcome is None:
            observation = episode.observe()
            c0 = time.perf_counter()
            try:
                raw = planner.act(observation)
                raw_v, raw_w = float(raw[0]), float(raw[1])
            except KeyboardInterrupt:
                raise
            except EndEpisode as exc:  # ended on purpose (e.g. the operator pressed Escape)
                episode.end(Outcome.ERROR, str(exc) or "ended by the planner")
                break
            except Exception as exc:  # the planner is foreign code: report, don't crash
                episode.end(Outcome.ERROR, f"planner raised {type(exc).__name__}: {exc}")
                break
            episode.planner_ms[episode.n_ticks] = (time.perf_counter() - c0) * 1e3
            first = episode.step
            if episode.apply(raw_v, raw_w) is Outcome.ERROR:
                break
            if observers:
                tick = episode.tick_record(planner.debug())
                for obs_ in observers:
                    obs_.on_tick(tick)
                times, poses = episode.poses_between(first)
                if len(times):
                    for obs_ in observers:
                        obs_.on_poses(times, poses)
    except KeyboardInterrupt:
        episode.end(Outcome.ERROR, "interrupted")
        result = episode.result(start)
        for obs_ in observers:
            obs_.on_end(result)
        raise
    result = episode.result(start)
    for obs_ in observers:
        obs_.on_end(result)
    return result


def _predictor(player: SchedulePlayer):
    """Exact future obstacle positions: (n, 2) for a time, (T, n, 2) for an array of times."""

    def predict(t_future):
        arr = np.asarray(t_future, dtype=np.float64)
        pos, _ = player.positions_at(np.atleast_1d(arr))
        return pos if arr.ndim else pos[0]

    return predict


def _constant_velocity(t0: float, xy: np.ndarray, vel: np.ndarray):
    """Reactive obstacles' future depends on the robot: extrapolate their present motion."""
    xy, vel = xy.copy(), vel.copy()

    def predict(t_future):
        arr = np.asarray(t_future, dtype=np.float64)
        dt = np.atleast_1d(arr) - t0
        pos = xy[None] + dt[:, None, None] * vel[None]
        return pos if arr.ndim else pos[0]

    return predict


def _optimal_length(protocol: EvalProtocol, world: WorldSpec, goal: tuple[float, float]) -> float:
    """SPL's shortest path: the world's reference path when the protocol says so, else a straight line."""
    ref = world.provenance.get("reference_path_length") if protocol.reference_from_world else None
    if ref is not None:
        return max(float(ref) - protocol.goal_tolerance, 0.0)
    return protocol.optimal_path_length(goal)


def _contact_partner(model: mujoco.MjModel, data: mujoco.MjData, robot_geoms: set[int]) -> str:
    con = data.contact[0]
    g1, g2 = int(con.geom[0]), int(con.geom[1])
    other = g2 if g1 in robot_geoms else g1
    return model.geom(other).name or f"geom {other}"


def _finish(episode: Episode, start: EpisodeStart) -> EpisodeResult:
    sim = episode.sim
    cfg = sim.config
    protocol = start.protocol
    outcome, reason, step, t_start = episode.outcome, episode.reason, episode.step, episode.t_start
    n_ticks = episode.n_ticks
    sim_time = step * cfg.dt
    traj = episode.poses[: step + 1]
    # The protocol's clock: from the first `timer_start_distance` of motion, if any.
    ep_time = sim_time - t_start if t_start is not None else sim_time
    success = outcome is Outcome.SUCCESS
    length = path_length(traj[:, :2])
    # Clearance at every physics step, from one batched schedule evaluation.
    if episode.reactive:
        obstacle_xy = episode.obstacle_log[: step + 1]
        obstacle_xy[step] = episode.obstacle_log[max(step - 1, 0)] if step else obstacle_xy[0]
    else:
        obstacle_xy, _ = episode.player.positions_at(np.arange(step + 1) * cfg.dt)
    clearance = sim.clearance(traj, obstacle_xy, static=True)
    mean_ms, p95_ms = compute_percentiles(episode.planner_ms[:n_ticks])
    wall = time.perf_counter() - episode.wall_t0
    goal = (float(sim.goal[0]), float(sim.goal[1]))
    tick_v, tick_w, tick_w_cmd = episode.tick_v, episode.tick_w, episode.tick_w_cmd
    return EpisodeResult(
        world=sim.world.name,
        planner=start.planner,
        protocol=protocol.name,
        seed=start.seed,
        outcome=outcome,
        reason=reason,
        time=ep_time,
        sim_time=sim_time,
        path_length=length,
        score=protocol.score(
            success,
            ep_time,
            sim.world.provenance.get("reference_path_length") if protocol.reference_from_world else None,
        ),
        spl=spl(success, _optimal_length(protocol, sim.world, goal), length),
        min_clearance=float(clearance.min()) if clearance.size else math.inf,
        mean_abs_jerk=mean_abs_jerk(tick_v[:n_ticks], cfg.control_period),
        sum_abs_dw=sum_abs_change(tick_w_cmd[:n_ticks]),
        time_stalled=stalled_time(tick_v[:n_ticks], tick_w[:n_ticks], cfg.control_period),
        planner_ms_mean=mean_ms,
        planner_ms_p95=p95_ms,
        rtf=sim_time / wall if wall > 0 else math.inf,
        wall_time=wall,
        clock_offset=start.clock_offset,
        n_ticks=n_ticks,
        world_file=portable_path(sim.world_path),
        world_sha256=sim.world_sha256,
        versions=start.versions,
        machine=machine(),
        planner_config=start.planner_config,
        protocol_version=protocol.version,
    )
