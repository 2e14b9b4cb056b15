"""`trajectory_planner`: base_local_planner's TrajectoryPlanner (TrajectoryPlannerROS with
`dwa: true`), the local planner the BARN Challenge's and the DynaBARN authors' move_base
launch files name, where it differs from `dwa` (which scores as dwa_local_planner does).

What this planner does as base_local_planner/src/trajectory_planner.cpp does (navigation
noetic-devel), each a switch of its own so that a comparison can take them one at a time:
- `ramp`: a rollout starts at the measured velocity and accelerates to its sample at the
  limits (Euler steps, the pose updated with the new velocity), and its first point is the
  robot's pose now; `dwa`'s are constant-velocity arcs from the first step.
- `score_at_end`: the path and goal distances are those of the rollout's last point, with
  no point pushed ahead (`heading_scoring: false`), the local goal `lookahead` along the
  plan (there: the plan's last point inside the 10 m local costmap, 5 m away).
- `rotate_in_place`: when every forward sample is blocked, or a rotation costs no more than
  the best of them, the robot stops and turns (samples at v = 0, |w| at least
  `min_in_place_vel_theta`), towards the rotation whose heading point ends nearest the goal.
  This is how move_base's DWA waits for an obstacle to pass; `dwa` keeps driving forward
  (at least `min_vel_x`) or backs up.
- `ros_escape`, as there: nothing admissible, back up straight at `escape_vel` (turning only by
  rotations) until moved `escape_reset_dist` or turned `escape_reset_theta`; with the
  robot's own cell blocked, stop.
- `slow_near_goal`: max_vel_x <= (distance to the goal) / sim_time.
- `sim_period`: the dynamic window is acc x sim_period wide (1 / controller_frequency, 0.05
  s at move_base's 20 Hz), not the control period.

With `include_dynamic_obstacles` the tracker's tracks are checked as in `dwa`. Not
reproduced: the path and goal distances are Euclidean (there: 4-connected flood fills
over the local costmap), the footprint's edges are not checked against lethal cells
separately (the circle of `collision_radius` is the padded footprint's inscribed one), and
the oscillation flags (`stuck_left` / `stuck_right`) are left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dynabarn.determinism import sincos
from dynabarn.interfaces import EpisodeInfo, Observation, config_from_kwargs
from dynabarn.planners.costmap import with_costmap
from dynabarn.planners.dwa import DWAConfig, DWAPlanner, rollout, sample_grid
from dynabarn.planners.tracking import with_tracker


@dataclass
class TrajectoryPlannerConfig(DWAConfig):
    ramp: bool = True
    """Rollouts accelerate from the measured velocity at the limits (TrajectoryPlanner)."""
    score_at_end: bool = True
    """Path and goal distances of the rollout's last point, no point ahead."""
    rotate_in_place: bool = True
    """Sample stopping and turning in place (TrajectoryPlanner's rotation samples)."""
    min_in_place_vel_theta: float = 0.4
    """Smallest |w| of an in-place rotation [rad/s] (base_local_planner default)."""
    ros_escape: bool = True
    """Nothing admissible: back up straight, or stop when the robot's own cell is blocked."""
    escape_reset_dist: float = 0.1
    """Escaping ends after moving this far [m] (base_local_planner default)."""
    escape_reset_theta: float = math.pi / 4
    """... or turning this much [rad] (base_local_planner default pi/4)."""
    slow_near_goal: bool = True
    """max_vel_x <= distance to the goal / sim_time."""
    sim_period: float = 0.05
    """The dynamic window's time [s]: 1 / move_base's controller_frequency (20 Hz); 0 takes
    the control period."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        **DWAConfig.LIMITS,
        "min_in_place_vel_theta": (0.0, 10.0),
        "escape_reset_dist": (0.0, 10.0),
        "escape_reset_theta": (0.0, math.pi),
        "sim_period": (0.0, 1.0),
    }

    @classmethod
    def from_kwargs(cls, **kwargs) -> TrajectoryPlannerConfig:
        what = "trajectory_planner"
        return config_from_kwargs(cls, with_tracker(with_costmap(kwargs, what), what), what)


def ramped_rollout(
    pose: np.ndarray, v0: float, w0: float, v: np.ndarray, w: np.ndarray, acc: tuple[float, float], dt: float, n: int
) -> np.ndarray:
    """TrajectoryPlanner's rollouts: poses (n_samples, n, 3), the first the pose now; each step
    moves the velocity towards its sample by at most acc x dt, then the pose with it."""
    steps = np.arange(1, n)[None, :] * dt
    vk = v0 + np.clip(v[:, None] - v0, -acc[0] * steps, acc[0] * steps)
    wk = w0 + np.clip(w[:, None] - w0, -acc[1] * steps, acc[1] * steps)
    th = np.empty((len(v), n))
    th[:, 0] = pose[2]
    np.cumsum(wk * dt, axis=1, out=th[:, 1:])
    th[:, 1:] += pose[2]
    sin_th, cos_th = sincos(th[:, :-1])  # the heading before each step, as there
    xy = np.empty((len(v), n, 2))
    xy[:, 0] = pose[:2]
    np.cumsum(vk * cos_th * dt, axis=1, out=xy[:, 1:, 0])
    np.cumsum(vk * sin_th * dt, axis=1, out=xy[:, 1:, 1])
    xy[:, 1:] += pose[:2]
    return np.concatenate([xy, th[..., None]], axis=-1)


class TrajectoryPlanner(DWAPlanner):
    """base_local_planner's TrajectoryPlanner (`dwa: true`) on `dwa`'s costmap and plan."""

    name = "trajectory_planner"
    config_class = TrajectoryPlannerConfig

    def __init__(self, **config) -> None:
        super().__init__(**config)
        self._steps = len(self._times)
        # When each rollout point is, from now: a ramped rollout starts at the pose now.
        self._point_times = np.arange(self._steps) * self.cfg.sim_dt if self.cfg.ramp else self._times

    def reset(self, info: EpisodeInfo) -> None:
        super().reset(info)
        self._escaping_from: np.ndarray | None = None

    def act(self, obs: Observation) -> tuple[float, float]:
        """One control tick of TrajectoryPlanner::createTrajectories, in its order."""
        cfg, info = self.cfg, self.info
        pose = obs.pose
        local_goal, near = self._perceive_and_plan(obs)
        goal_dist_now = float(np.hypot(*(pose[:2] - info.goal)))
        v_now, w_now = float(obs.velocity[0]), float(obs.velocity[1])  # odometry, as in ROS
        v, w, n_forward = self._samples(v_now, w_now, goal_dist_now)
        traj = self._rollouts(pose, v_now, w_now, v, w)
        ok = self._admissible(traj[..., :2], obs.time, self._point_times)
        latched = goal_dist_now < cfg.lookahead
        total, front = self._scores(traj, ok, near, local_goal, goal_latched=latched, at_end=cfg.score_at_end)
        best = int(np.argmin(total[:n_forward])) if n_forward else -1
        best_cost = float(total[best]) if n_forward else math.inf
        if len(v) > n_forward:
            # A rotation replaces the best forward sample when it costs no more: the one whose
            # point ahead ends nearest the goal (TrajectoryPlanner's heading_dist).
            ahead = np.hypot(*(front[n_forward:] - (info.goal if latched else local_goal)).T)
            heading_dist = math.inf
            for k in range(n_forward, len(v)):
                if ok[k] and total[k] <= best_cost and ahead[k - n_forward] < heading_dist:
                    best, best_cost, heading_dist = k, float(total[k]), float(ahead[k - n_forward])
        if best >= 0 and math.isfinite(best_cost):
            self._end_escape(pose)
            self._last_plan = traj[best, :, :2]
            self._prev = np.array([v[best], w[best]])
            return float(v[best]), float(w[best])
        return self._ros_escape(obs) if cfg.ros_escape else self._escape(obs)

    def _samples(self, v_now: float, w_now: float, goal_dist: float) -> tuple[np.ndarray, np.ndarray, int]:
        """The (v, w) samples: the forward ones first (none while escaping), then the in-place
        rotations; and how many are forward."""
        cfg = self.cfg
        period = cfg.sim_period or self.period
        dv, dw = cfg.acc_lim_x * period, cfg.acc_lim_theta * period
        top = min(cfg.max_vel_x, goal_dist / cfg.sim_time) if cfg.slow_near_goal else cfg.max_vel_x
        v_hi = max(min(top, v_now + dv), cfg.min_vel_x)
        v_lo = min(max(cfg.min_vel_x, v_now - dv), v_hi)
        w_lo, w_hi = max(-cfg.max_vel_theta, w_now - dw), min(cfg.max_vel_theta, w_now + dw)
        escaping = self._escaping_from is not None and cfg.ros_escape
        forward_v = np.zeros(0) if escaping else np.linspace(v_lo, v_hi, cfg.vx_samples)
        v, w = sample_grid(forward_v, w_lo, w_hi, cfg.vth_samples)
        n_forward = len(v)
        if cfg.rotate_in_place:
            turn = np.linspace(w_lo, w_hi, cfg.vth_samples)
            dtheta = (w_hi - w_lo) / max(cfg.vth_samples - 1, 1)
            turn = turn[np.abs(turn) > dtheta]
            turn = np.sign(turn) * np.maximum(np.abs(turn), cfg.min_in_place_vel_theta)
            v = np.concatenate([v, np.zeros(len(turn))])
            w = np.concatenate([w, turn])
        return v, w, n_forward

    def _rollouts(self, pose: np.ndarray, v_now: float, w_now: float, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        cfg = self.cfg
        if cfg.ramp:
            return ramped_rollout(pose, v_now, w_now, v, w, (cfg.acc_lim_x, cfg.acc_lim_theta), cfg.sim_dt, self._steps)
        return rollout(pose, v, w, self._times)

    def _end_escape(self, pose: np.ndarray) -> None:
        start = self._escaping_from
        if start is None:
            return
        turned = abs(math.remainder(float(pose[2] - start[2]), math.tau))
        if math.hypot(pose[0] - start[0], pose[1] - start[1]) > self.cfg.escape_reset_dist or (
            turned > self.cfg.escape_reset_theta
        ):
            self._escaping_from = None

    def _ros_escape(self, obs: Observation) -> tuple[float, float]:
        """Back up straight at escape_vel; stop when the robot's own cell is blocked."""
        cfg = self.cfg
        here = float(self.costmap.lookup(obs.pose[None, :2], self.costmap.distance, outside=np.inf)[0])
        self._last_plan = np.zeros((0, 2))
        if here < cfg.collision_radius:
            self._prev = np.zeros(2)
            return 0.0, 0.0
        if self._escaping_from is None:
            self._escaping_from = np.array(obs.pose, dtype=float)
        self._end_escape(obs.pose)
        self._prev = np.array([cfg.escape_vel, 0.0])
        return cfg.escape_vel, 0.0
