"""`teb`: a Timed Elastic Band (Roesmann et al. 2012, 2013), optimised with sparse least
squares, after teb_local_planner.

The band is a sequence of poses s_i = (x_i, y_i, theta_i), i = 0..N-1, and the time
intervals dT_i between them. The first pose is the robot's, the last the local goal
(`lookahead` metres along the Dijkstra global plan, heading along the plan); the poses in
between and all dT_i (as log dT, so intervals stay positive) are optimised with
Levenberg-Marquardt (`levenberg_marquardt.py`: the same bits on every CPU) against teb_local_planner's
soft constraints, each a weighted residual. Each residual touches one to three neighbouring
poses, so the forward-difference Jacobian takes a dozen batched rows (`coloured_jacobian`):

- time optimality: dT_i (`weight_optimaltime` 1);
- non-holonomic kinematics: (cos th_i + cos th_i+1) dy_i - (sin th_i + sin th_i+1) dx_i
  (`weight_kinematics_nh` 1000);
- forward drive: max(0, -(direction of motion . heading)) (`weight_kinematics_forward_drive` 1);
- velocity limits: max(0, abs(v_i) - max_vel_x) (backwards: max_vel_x_backwards),
  max(0, abs(w_i) - max_vel_theta) (`weight_max_vel_x` 2, `weight_max_vel_theta` 1);
- acceleration limits: max(0, abs(dv / dt) - acc_lim_x), max(0, abs(dw / dt) - acc_lim_theta)
  (`weight_acc_lim_x` 1, `weight_acc_lim_theta` 1);
- obstacle clearance: max(0, min_obstacle_dist - d(s_i, nearest laser point)) (`weight_obstacle` 50);
- inflation: max(0, inflation_dist - d(s_i, nearest laser point)) (`weight_inflation` 0.5).

Laser returns within `obstacle_range` (one in `obstacle_stride` beams) are the obstacles,
as teb_local_planner sees costmap cells without a costmap converter; like the paper's
TEB it does not predict obstacle motion. The band is warm-started from the previous tick
(resampled to start at the robot); the command is its first segment's velocity. When the
band's first poses stay in collision, the planner backs up (recovery), as move_base would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from dynabarn.determinism import STATE_RESOLUTION, exp, sincos, snap_array
from dynabarn.interfaces import CheckedConfig, EpisodeInfo, Observation, Planner, config_from_kwargs, recorded_config
from dynabarn.perception import TrackerConfig, Tracks
from dynabarn.perception.trackers import make_tracker
from dynabarn.planners.coloured_jacobian import Colouring, residuals_and_jacobian
from dynabarn.planners.costmap import CostmapConfig, LocalCostmap, with_costmap
from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.planners.levenberg_marquardt import Evaluation, minimise
from dynabarn.planners.tracking import UncertaintyPadding, distance_to_tracks, track_moving, with_tracker


@dataclass
class TEBConfig(UncertaintyPadding, CheckedConfig):
    n_poses: int = 12
    """Poses in the band (including start and goal)."""
    lookahead: float = 3.0
    """Local goal distance along the global plan [m]."""
    max_vel_x: float = 2.0
    max_vel_x_backwards: float = 0.5
    max_vel_theta: float = 3.0
    acc_lim_x: float = 2.5
    acc_lim_theta: float = 5.0
    min_obstacle_dist: float = 0.45
    """Required distance from a band pose to a laser point [m] (footprint radius 0.333 + margin)."""
    inflation_dist: float = 0.9
    obstacle_range: float = 5.0
    obstacle_stride: int = 4
    weight_optimaltime: float = 1.0
    weight_kinematics_nh: float = 1000.0
    weight_kinematics_forward_drive: float = 1.0
    weight_max_vel_x: float = 2.0
    weight_max_vel_theta: float = 1.0
    weight_acc_lim_x: float = 1.0
    weight_acc_lim_theta: float = 1.0
    weight_obstacle: float = 50.0
    weight_inflation: float = 0.5
    max_iterations: int = 12
    """Residual evaluations allowed per tick (the optimiser's `max_nfev`)."""
    include_dynamic_obstacles: bool = False
    """teb_local_planner's switch: track the moving obstacles with the laser tracker
    (`perception`), take their returns out of the static obstacles, and keep every band pose
    clear of each track at constant velocity at that pose's time (`uncertainty_sigmas`)."""
    weight_dynamic_obstacle: float = 50.0
    """teb_local_planner's default."""
    weight_dynamic_obstacle_inflation: float = 0.1
    dynamic_obstacle_inflation_dist: float = 0.6
    """teb_local_planner's default [m]."""
    costmap: CostmapConfig = field(default_factory=CostmapConfig)
    """The local costmap the replanning around blocked stretches of the global plan uses."""
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    """The tracker's parameters (with `include_dynamic_obstacles`)."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        **UncertaintyPadding.PADDING_LIMITS,
        "n_poses": (3, 100),
        "lookahead": (0.1, 30.0),
        "max_vel_x": (0.0, 5.0),
        "max_vel_x_backwards": (0.0, 5.0),
        "max_vel_theta": (0.0, 10.0),
        "acc_lim_x": (1e-3, 100.0),
        "acc_lim_theta": (1e-3, 100.0),
        "min_obstacle_dist": (0.0, 3.0),
        "inflation_dist": (0.0, 5.0),
        "obstacle_range": (0.0, 30.0),
        "obstacle_stride": (1, 720),
        "max_iterations": (1, 1000),
        "dynamic_obstacle_inflation_dist": (0.0, 5.0),
        **{
            w: (0.0, 1e6)
            for w in (
                "weight_optimaltime",
                "weight_kinematics_nh",
                "weight_kinematics_forward_drive",
                "weight_max_vel_x",
                "weight_max_vel_theta",
                "weight_acc_lim_x",
                "weight_acc_lim_theta",
                "weight_obstacle",
                "weight_inflation",
                "weight_dynamic_obstacle",
                "weight_dynamic_obstacle_inflation",
            )
        },
    }
    """Accepted ranges (checked before a run)."""
    ORDERED: ClassVar[tuple[tuple[str, str], ...]] = (("min_obstacle_dist", "inflation_dist"),)
    """The inflation zone lies beyond the minimum distance (teb_local_planner's reading)."""

    @classmethod
    def from_kwargs(cls, **kwargs) -> TEBConfig:
        return config_from_kwargs(cls, with_tracker(with_costmap(kwargs, "TEB"), "TEB"), "TEB")


def _headings(d: np.ndarray) -> np.ndarray:
    """Directions of the segments d (m, 2) with libm's atan2 (numpy's differs between CPUs)."""
    return np.array([math.atan2(dy, dx) for dx, dy in d.tolist()])


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


class TEBPlanner(Planner):
    """Timed Elastic Band local planner with a Dijkstra global plan."""

    name = "teb"

    def __init__(self, **config) -> None:
        self.cfg = TEBConfig.from_kwargs(**config)
        n = self.cfg.n_poses
        self._n_free = n - 2
        c = self.cfg
        self._sqrt_weights = np.sqrt(
            [
                c.weight_optimaltime,
                c.weight_kinematics_nh,
                c.weight_kinematics_forward_drive,
                c.weight_max_vel_x,
                c.weight_max_vel_theta,
                c.weight_acc_lim_x,
                c.weight_acc_lim_theta,
                c.weight_obstacle,
                c.weight_inflation,
                c.weight_dynamic_obstacle,
                c.weight_dynamic_obstacle_inflation,
            ]
        )
        self._band: np.ndarray | None = None  # (n, 3)
        self._dts: np.ndarray | None = None  # (n - 1,)
        self._colourings: dict[tuple, Colouring] = {}

    def config(self) -> dict:
        return recorded_config(self.cfg)

    def reset(self, info: EpisodeInfo) -> None:
        self.info = info
        self.global_planner = GlobalPlanner.for_robot(info.walls, info.goal, info.footprint, info.static_obstacles)
        self._band = None
        self._dts = None
        self._global_plan = np.zeros((0, 2))
        self._rerouted = self._was_rerouted = False
        self.costmap = LocalCostmap(self.cfg.costmap)
        self._beams = np.arange(0, len(info.laser_angles), self.cfg.obstacle_stride)
        self.tracker = make_tracker(self.cfg.tracker, info) if self.cfg.include_dynamic_obstacles else None
        self._tracks: Tracks | None = None

    def tracks(self) -> Tracks | None:
        return self._tracks

    def debug(self) -> dict:
        plans = {"local_plan": self._band[:, :2] if self._band is not None else (), "global_plan": self._global_plan}
        return {k: v for k, v in plans.items() if len(v)}

    # -- band construction -----------------------------------------------------------------
    def _initial_band(self, start: np.ndarray, goal: np.ndarray, path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A fresh band along the global plan from the robot to the local goal."""
        n = self.cfg.n_poses
        seg = np.hypot(*np.diff(path, axis=0).T)
        along = np.concatenate([[0.0], np.cumsum(seg)])
        length = min(self.cfg.lookahead, along[-1])
        s = np.linspace(0.0, length, n)
        xy = np.column_stack([np.interp(s, along, path[:, 0]), np.interp(s, along, path[:, 1])])
        xy[0], xy[-1] = start[:2], goal[:2]
        d = np.diff(xy, axis=0)
        th = np.empty(n)
        th[:-1] = _headings(d)
        th[0], th[-1] = start[2], goal[2]
        band = np.column_stack([xy, th])
        dseg = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2)
        return band, np.maximum(dseg / (0.7 * self.cfg.max_vel_x), 0.05)

    def _warm_band(self, start: np.ndarray, goal: np.ndarray, path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Previous band re-anchored at the robot and the new goal, resampled along its length;
        a fresh band along the plan when there is none or the plan was rerouted."""
        if self._band is None or self._rerouted:
            return self._initial_band(start, goal, path)
        prev = self._band
        # Drop the poses the robot has passed: keep from the band pose closest to it.
        k = int(np.argmin(np.hypot(*(prev[:, :2] - start[:2]).T)))
        pts = np.vstack([start[None, :2], prev[k + 1 : -1, :2], goal[None, :2]])
        seg = np.hypot(*np.diff(pts, axis=0).T)
        along = np.concatenate([[0.0], np.cumsum(seg)])
        if along[-1] < 1e-6:
            return self._initial_band(start, goal, path)
        s = np.linspace(0.0, along[-1], self.cfg.n_poses)
        xy = np.column_stack([np.interp(s, along, pts[:, 0]), np.interp(s, along, pts[:, 1])])
        d = np.diff(xy, axis=0)
        th = np.empty(self.cfg.n_poses)
        th[:-1] = _headings(d)
        th[0], th[-1] = start[2], goal[2]
        dseg = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2)
        total_time = float(self._dts[k:].sum()) if k < len(self._dts) else along[-1] / self.cfg.max_vel_x
        dts = np.maximum(dseg / max(along[-1], 1e-6) * max(total_time, 0.1), 0.02)
        return np.column_stack([xy, th]), dts

    # -- optimisation --------------------------------------------------------------------------
    def _pack(self, band: np.ndarray, dts: np.ndarray) -> np.ndarray:
        return np.concatenate([band[1:-1].ravel(), [math.log(t) for t in dts.tolist()]])

    def _unpack(self, z: np.ndarray, start: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Band (..., n, 3) and intervals (..., n - 1) from variables z (..., n_var)."""
        m = self._n_free
        lead = z.shape[:-1]
        inner = z[..., : 3 * m].reshape(*lead, m, 3)
        band = np.concatenate(
            [np.broadcast_to(start, (*lead, 1, 3)), inner, np.broadcast_to(goal, (*lead, 1, 3))], axis=-2
        )
        return band, exp(np.clip(z[..., 3 * m :], -7.0, 3.0))  # dT in [1 ms, 20 s]

    def _residuals(
        self, z: np.ndarray, start: np.ndarray, goal: np.ndarray, obstacles: np.ndarray, moving: Tracks | None = None
    ) -> np.ndarray:
        """Weighted residuals (..., n_res) for variables z (..., n_var): batched over leading
        axes. `moving`: tracked obstacles, each kept clear of at the band pose's time."""
        cfg = self.cfg
        band, dts = self._unpack(z, start, goal)
        x, y, th = band[..., 0], band[..., 1], band[..., 2]
        dx, dy = np.diff(x, axis=-1), np.diff(y, axis=-1)
        dth = _wrap(np.diff(th, axis=-1))
        dist = np.sqrt(dx * dx + dy * dy)
        s, c = sincos(th)
        # Direction of motion relative to the heading: + forwards, - backwards.
        along = dx * c[..., :-1] + dy * s[..., :-1]
        v = np.sign(along) * dist / dts
        w = dth / dts
        nh = (c[..., :-1] + c[..., 1:]) * dy - (s[..., :-1] + s[..., 1:]) * dx
        fwd = np.maximum(0.0, -along)
        v_over = np.maximum(0.0, v - cfg.max_vel_x) + np.maximum(0.0, -v - cfg.max_vel_x_backwards)
        w_over = np.maximum(0.0, np.abs(w) - cfg.max_vel_theta)
        mid_dt = 0.5 * (dts[..., :-1] + dts[..., 1:])
        a_over = np.maximum(0.0, np.abs(np.diff(v, axis=-1) / mid_dt) - cfg.acc_lim_x)
        alpha_over = np.maximum(0.0, np.abs(np.diff(w, axis=-1) / mid_dt) - cfg.acc_lim_theta)
        if len(obstacles):
            ox, oy = obstacles[:, 0], obstacles[:, 1]
            ex, ey = x[..., 1:-1, None] - ox, y[..., 1:-1, None] - oy
            d = np.sqrt(ex * ex + ey * ey).min(axis=-1)
        else:
            d = np.full(x[..., 1:-1].shape, np.inf)
        w_ = self._sqrt_weights
        parts = [
            w_[0] * dts,
            w_[1] * nh,
            w_[2] * fwd,
            w_[3] * v_over,
            w_[4] * w_over,
            w_[5] * a_over,
            w_[6] * alpha_over,
            w_[7] * np.maximum(0.0, cfg.min_obstacle_dist - d),
            w_[8] * np.maximum(0.0, cfg.inflation_dist - d),
        ]
        if moving is not None:
            ahead = np.cumsum(dts, axis=-1)[..., :-1]  # seconds from now to each inner pose
            dm = distance_to_tracks(x[..., 1:-1], y[..., 1:-1], ahead, moving, cfg)
            parts += [
                w_[9] * np.maximum(0.0, cfg.min_obstacle_dist - dm),
                w_[10] * np.maximum(0.0, cfg.dynamic_obstacle_inflation_dist - dm),
            ]
        return np.concatenate(parts, axis=-1)

    def _evaluate(
        self, z: np.ndarray, start: np.ndarray, goal: np.ndarray, obstacles: np.ndarray, moving: Tracks | None
    ) -> Evaluation:
        """The residuals at z and their Jacobian from one batched evaluation (`coloured_jacobian`);
        which residuals each variable moves depends on whether there are points and tracks only."""

        def residuals(batch: np.ndarray) -> np.ndarray:
            return self._residuals(batch, start, goal, obstacles, moving)

        key = (len(obstacles) > 0, None if moving is None else len(moving) > 0)
        if key not in self._colourings:
            self._colourings[key] = Colouring.probe(residuals, z)
        return residuals_and_jacobian(residuals, z, self._colourings[key])

    def _obstacle_points(self, obs: Observation, moving_beams: np.ndarray | None = None) -> np.ndarray:
        """Laser returns within `obstacle_range` (one in `obstacle_stride` beams), world
        frame; without the beams that ended on tracked obstacles when `moving_beams` is given."""
        info = self.info
        idx = self._beams
        r = obs.scan[idx]
        keep = (r < self.cfg.obstacle_range) & (r < info.laser_range[1] - 1e-6)
        if moving_beams is not None:
            keep &= ~moving_beams[idx]
        a = info.laser_angles[idx][keep] + obs.pose[2]
        x0, y0, yaw = obs.pose
        lx = x0 + math.cos(yaw) * info.laser_offset[0]
        ly = y0 + math.sin(yaw) * info.laser_offset[0]
        sin_a, cos_a = sincos(a)
        return np.column_stack([lx + r[keep] * cos_a, ly + r[keep] * sin_a])

    def act(self, obs: Observation) -> tuple[float, float]:
        cfg = self.cfg
        start = obs.pose.astype(np.float64).copy()
        info = self.info
        scan, moving, moving_beams = obs.scan, None, None
        if self.tracker is not None:
            # The moving obstacles are the tracker's: the costmap (and with it the replanning
            # around blocked stretches of the plan) sees only what stands still.
            self._tracks, moving_beams, scan = track_moving(self.tracker, obs, info.laser_range[1])
            moving = self._tracks.covering_circles()  # outlines as circles
        self.costmap.update(start, scan, info.laser_angles, info.laser_offset, info.laser_range[1])
        path = self.global_planner.plan_around(start[0], start[1], self.costmap, block_radius=cfg.min_obstacle_dist)
        rerouted = len(path) != len(self.global_planner.plan(start[0], start[1]))
        self._rerouted = rerouted and not self._was_rerouted
        self._was_rerouted = rerouted
        local_goal, path = self.global_planner.local_goal(start[0], start[1], cfg.lookahead, path)
        self._global_plan = path
        if np.hypot(*(start[:2] - self.info.goal)) < cfg.lookahead:
            goal_heading = math.atan2(local_goal[1] - start[1], local_goal[0] - start[0])
        else:
            k = min(int(np.searchsorted(np.cumsum(np.hypot(*np.diff(path, axis=0).T)), cfg.lookahead)), len(path) - 2)
            goal_heading = math.atan2(path[k + 1, 1] - path[k, 1], path[k + 1, 0] - path[k, 0])
        goal = np.array([local_goal[0], local_goal[1], goal_heading])
        obstacles = self._obstacle_points(obs, moving_beams)
        band, dts = self._warm_band(start, goal, path)
        # Headings unwrapped around the start so the optimiser never sees a 2 pi jump.
        band[:, 2] = start[2] + _wrap(band[:, 2] - start[2])
        goal[2] = band[-1, 2]
        z0 = self._pack(band, dts)
        sol = minimise(
            lambda z: self._evaluate(z, start, goal, obstacles, moving),
            z0,
            max_nfev=cfg.max_iterations,
        )
        band, dts = self._unpack(sol.x, start, goal)
        # The band on a fixed grid, so the warm start and the command drawn from it stay on
        # the grid even where numpy's own kernels (exp's ldexp, sqrt) were to differ.
        snap_array(band, STATE_RESOLUTION, out=band)
        snap_array(dts, STATE_RESOLUTION, out=dts)
        self._band, self._dts = band, dts
        if len(obstacles):
            d = np.hypot(band[:3, None, 0] - obstacles[None, :, 0], band[:3, None, 1] - obstacles[None, :, 1]).min()
            if d < 0.5 * math.hypot(*self.info.footprint):
                return self._recover(start, obstacles)
        d0 = band[1, :2] - band[0, :2]
        along = d0[0] * math.cos(start[2]) + d0[1] * math.sin(start[2])
        v = math.copysign(math.hypot(*d0), along) / dts[0]
        w = float(_wrap(np.array([band[1, 2] - band[0, 2]]))[0]) / dts[0]
        v = min(max(v, -cfg.max_vel_x_backwards), cfg.max_vel_x)
        w = min(max(w, -cfg.max_vel_theta), cfg.max_vel_theta)
        return v, w

    def _recover(self, start: np.ndarray, obstacles: np.ndarray) -> tuple[float, float]:
        """Back up away from the nearest obstacle point, turning the other way."""
        self._band = None
        k = int(np.argmin(np.hypot(*(obstacles - start[:2]).T)))
        rel = obstacles[k] - start[:2]
        bearing = _wrap(np.array([math.atan2(rel[1], rel[0]) - start[2]]))[0]
        if abs(bearing) < math.pi / 2:  # obstacle ahead: reverse, turning away
            return -self.cfg.max_vel_x_backwards, -math.copysign(1.0, bearing)
        return 0.5, math.copysign(1.0, bearing)
