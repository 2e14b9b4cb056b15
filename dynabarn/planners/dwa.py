"""`dwa`: the Dynamic Window Approach (Fox, Burgard, Thrun 1997) as ROS's
dwa_local_planner scores it, vectorised (`trajectory_planner.py`: base_local_planner's
TrajectoryPlanner, which BARN's move_base configuration runs, built on this).

Per control tick:
1. update the rolling local costmap from the scan (`costmap.py`);
2. take the global plan (Dijkstra on the static map) and a local goal `lookahead` metres
   along it;
3. sample (v, w) inside the dynamic window reachable within one control period under the
   acceleration limits (`vx_samples` x `vth_samples`, plus w = 0 and the current command);
4. forward-simulate each sample as a constant-velocity arc for `sim_time` seconds;
5. reject trajectories that pass within `collision_radius` of an obstacle cell; score the
   rest as dwa_local_planner does:
   `path_distance_bias * d(end, path) + goal_distance_bias * d(front, local goal)
   + path_distance_bias * d(front, path) + occdist_scale * max cost`
   (distances in costmap cells, as ROS counts them; `front` is the end point pushed
   `forward_point_distance` ahead along the final heading);
6. if nothing is admissible, escape: back up at `escape_vel` turning to the freer side,
   or rotate in place when even that is blocked.

Every parameter is a field of `DWAConfig` with its default; `--planner-config` overrides
them (`dwa.max_vel_x=1.5` style keys, or a JSON file).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from dynabarn.determinism import SCORE_RESOLUTION, hypot, sincos, snap_array
from dynabarn.interfaces import CheckedConfig, EpisodeInfo, Observation, Planner, config_from_kwargs, recorded_config
from dynabarn.perception import TrackerConfig, Tracks
from dynabarn.perception.trackers import make_tracker
from dynabarn.planners.costmap import CostmapConfig, LocalCostmap, with_costmap
from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.planners.tracking import UncertaintyPadding, distance_to_tracks, track_moving, with_tracker


@dataclass
class DWAConfig(UncertaintyPadding, CheckedConfig):
    max_vel_x: float = 2.0
    """Top forward speed sampled [m/s] (the Jackal's)."""
    min_vel_x: float = 0.0
    """Lowest forward speed sampled in normal operation [m/s]; backing up is the escape."""
    max_vel_theta: float = 3.0
    """Largest |w| sampled [rad/s]."""
    acc_lim_x: float = 2.5
    """Linear acceleration limit the window assumes [m/s^2] (base_local_planner default)."""
    acc_lim_theta: float = 5.0
    """Angular acceleration limit the window assumes [rad/s^2]."""
    sim_time: float = 1.7
    """Forward-simulation horizon [s] (base_local_planner default)."""
    sim_dt: float = 0.1
    """Forward-simulation step [s]."""
    vx_samples: int = 8
    vth_samples: int = 21
    path_distance_bias: float = 32.0
    """Weight of staying on the global path (ROS default)."""
    goal_distance_bias: float = 24.0
    """Weight of approaching the local goal (ROS default)."""
    occdist_scale: float = 0.02
    """Weight of the highest cost along the trajectory (ROS default 0.01)."""
    forward_point_distance: float = 0.325
    """Distance ahead of the end pose scored against the goal and path [m] (ROS default)."""
    lookahead: float = 3.0
    """Local goal distance along the global path [m]."""
    collision_radius: float = 0.36
    """Trajectories passing closer than this to an obstacle cell are rejected [m]
    (the footprint's circumscribed radius 0.333 plus a margin)."""
    escape_vel: float = -0.3
    """Backing-up speed when nothing is admissible [m/s]."""
    include_dynamic_obstacles: bool = False
    """Track the moving obstacles with the laser tracker (`perception`), take their returns
    out of the costmap, and reject rollouts that come within `collision_radius` of a track
    at constant velocity at the rollout's time (as TEB's switch of the same name), its radius
    grown by `uncertainty_sigmas` standard deviations of its predicted position."""
    costmap: CostmapConfig = field(default_factory=CostmapConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    """The tracker's parameters (with `include_dynamic_obstacles`)."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        **UncertaintyPadding.PADDING_LIMITS,
        "max_vel_x": (0.0, 5.0),
        "min_vel_x": (-2.0, 5.0),
        "max_vel_theta": (0.0, 10.0),
        "acc_lim_x": (1e-3, 100.0),
        "acc_lim_theta": (1e-3, 100.0),
        "sim_time": (1e-3, 10.0),
        "sim_dt": (1e-3, 1.0),
        "vx_samples": (1, 200),
        "vth_samples": (1, 400),
        "path_distance_bias": (0.0, 1e6),
        "goal_distance_bias": (0.0, 1e6),
        "occdist_scale": (0.0, 1e6),
        "forward_point_distance": (0.0, 5.0),
        "lookahead": (0.1, 30.0),
        "collision_radius": (0.0, 2.0),
        "escape_vel": (-2.0, 0.0),
    }
    """Accepted ranges (checked before a run: a typo cannot exhaust memory or time)."""
    ORDERED: ClassVar[tuple[tuple[str, str], ...]] = (("min_vel_x", "max_vel_x"), ("sim_dt", "sim_time"))
    """Fields that must not cross (`interfaces.planner.check_relations`)."""

    @classmethod
    def from_kwargs(cls, **kwargs) -> DWAConfig:
        return config_from_kwargs(cls, with_tracker(with_costmap(kwargs, "DWA"), "DWA"), "DWA")


def rollout(pose: np.ndarray, v: np.ndarray, w: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Constant-velocity arcs: poses (n_samples, n_times, 3) from pose (3,) for each (v, w)."""
    x0, y0, th0 = float(pose[0]), float(pose[1]), float(pose[2])
    v = v[:, None]
    w = w[:, None]
    t = times[None, :]
    th = th0 + w * t
    straight = np.abs(w) < 1e-6
    w_safe = np.where(straight, 1.0, w)
    sin_th, cos_th = sincos(th)  # the same bits on every CPU (numpy's sin and cos are not)
    x_arc = x0 + v / w_safe * (sin_th - math.sin(th0))
    y_arc = y0 - v / w_safe * (cos_th - math.cos(th0))
    x_line = x0 + v * t * math.cos(th0)
    y_line = y0 + v * t * math.sin(th0)
    x = np.where(straight, x_line, x_arc)
    y = np.where(straight, y_line, y_arc)
    return np.stack([x, y, np.broadcast_to(th, x.shape)], axis=-1)


def sample_grid(vs: np.ndarray, w_lo: float, w_hi: float, n_w: int) -> tuple[np.ndarray, np.ndarray]:
    """Every forward speed of `vs` with `n_w` yaw rates across [w_lo, w_hi], plus w = 0 when the
    window holds it: (v, w), flat, speed-major."""
    ws = np.unique(np.concatenate([np.linspace(w_lo, w_hi, n_w), [0.0] if w_lo <= 0 <= w_hi else []]))
    v, w = np.meshgrid(vs, ws, indexing="ij")
    return v.ravel(), w.ravel()


POLYLINE_CHUNK = 64
"""Points measured against a polyline together: their (points, segments) temporaries stay
in cache (the whole of 500 rollout ends against a 100-point plan did not)."""


def distance_to_polyline(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance from each point (n, 2) to the polyline path (m, 2). Each (point, segment)
    pair is evaluated alone, in x and y separately (a sum over an axis of two is the one
    addition written out), so the chunking changes no bit."""
    if len(path) == 1:
        return hypot(points[:, 0] - path[0, 0], points[:, 1] - path[0, 1])
    ax, ay = path[:-1, 0], path[:-1, 1]
    abx, aby = path[1:, 0] - ax, path[1:, 1] - ay
    denom = np.maximum(abx * abx + aby * aby, 1e-12)
    out = np.empty(len(points))
    for i in range(0, len(points), POLYLINE_CHUNK):
        px, py = points[i : i + POLYLINE_CHUNK, 0, None], points[i : i + POLYLINE_CHUNK, 1, None]
        apx, apy = px - ax, py - ay
        u = np.clip((apx * abx + apy * aby) / denom, 0.0, 1.0)
        out[i : i + POLYLINE_CHUNK] = hypot(px - (ax + u * abx), py - (ay + u * aby)).min(axis=1)
    return out


class DWAPlanner(Planner):
    """Dynamic Window Approach local planner with a Dijkstra global plan."""

    name = "dwa"
    config_class: ClassVar[type[DWAConfig]] = DWAConfig
    """The configuration a subclass extends (`trajectory_planner`)."""

    def __init__(self, **config) -> None:
        self.cfg = self.config_class.from_kwargs(**config)
        self._times = np.arange(1, round(self.cfg.sim_time / self.cfg.sim_dt) + 1) * self.cfg.sim_dt
        self._last_plan = np.zeros((0, 2))

    def config(self) -> dict:
        return recorded_config(self.cfg)

    def reset(self, info: EpisodeInfo) -> None:
        self.info = info
        self.costmap = LocalCostmap(self.cfg.costmap)
        self.global_planner = GlobalPlanner.for_robot(info.walls, info.goal, info.footprint, info.static_obstacles)
        self.period = info.control_period
        self._last_plan = np.zeros((0, 2))
        self._global_plan = np.zeros((0, 2))
        self._prev = np.zeros(2)
        self.tracker = make_tracker(self.cfg.tracker, info) if self.cfg.include_dynamic_obstacles else None
        self._tracks: Tracks | None = None

    def tracks(self) -> Tracks | None:
        return self._tracks

    def debug(self) -> dict:
        plans = {"local_plan": self._last_plan, "global_plan": self._global_plan}
        return {k: v for k, v in plans.items() if len(v)}

    def act(self, obs: Observation) -> tuple[float, float]:
        cfg, info = self.cfg, self.info
        pose = obs.pose
        local_goal, near = self._perceive_and_plan(obs)
        v_now, w_now = float(obs.velocity[0]), float(obs.velocity[1])  # odometry, as in ROS
        dv, dw = cfg.acc_lim_x * self.period, cfg.acc_lim_theta * self.period
        v_lo, v_hi = max(cfg.min_vel_x, v_now - dv), min(cfg.max_vel_x, v_now + dv)
        w_lo, w_hi = max(-cfg.max_vel_theta, w_now - dw), min(cfg.max_vel_theta, w_now + dw)
        if v_lo > v_hi:  # coming out of an escape: let the window reach min_vel_x
            v_lo = v_hi = min(max(cfg.min_vel_x, v_now + dv), cfg.max_vel_x)
        v, w = sample_grid(np.linspace(v_lo, v_hi, cfg.vx_samples), w_lo, w_hi, cfg.vth_samples)

        traj = rollout(pose, v, w, self._times)  # (N, K, 3)
        ok = self._admissible(traj[..., :2], obs.time, self._times)
        if not ok.any():
            return self._escape(obs)
        # The goal itself in reach: bring the robot's centre (not the point ahead of it) onto
        # the goal, and stop scoring the heading (dwa_local_planner's goal latch).
        latched = bool(np.hypot(*(pose[:2] - info.goal)) < cfg.lookahead)
        total, _ = self._scores(traj, ok, near, local_goal, goal_latched=latched, at_end=False)
        best = int(np.argmin(total))  # ties in exact arithmetic stay ties on every CPU; the first wins
        self._last_plan = traj[best, :, :2]
        self._prev = np.array([v[best], w[best]])
        return float(v[best]), float(w[best])

    def _perceive_and_plan(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        """Update the costmap from the scan (the tracker's moving obstacles taken out of it) and
        plan around what it holds: (the local goal, the part of the plan near the robot, at
        most `lookahead` + 1 m long, which rollouts are scored against)."""
        cfg, info = self.cfg, self.info
        pose = obs.pose
        scan = obs.scan
        if self.tracker is not None:
            # The moving obstacles are the tracker's: the costmap holds what stands still.
            self._tracks, _, scan = track_moving(self.tracker, obs, info.laser_range[1])
        self.costmap.update(pose, scan, info.laser_angles, info.laser_offset, info.laser_range[1])
        path = self.global_planner.plan_around(pose[0], pose[1], self.costmap, block_radius=cfg.collision_radius)
        local_goal, path = self.global_planner.local_goal(pose[0], pose[1], cfg.lookahead, path)
        self._global_plan = path
        return local_goal, path[: max(2, int((cfg.lookahead + 1.0) / self.global_planner.resolution) + 2)]

    def _admissible(self, xy: np.ndarray, now: float, times: np.ndarray) -> np.ndarray:
        """Which rollouts (N, K, 2), their points at `times` from now, keep `collision_radius`
        from every obstacle cell and from every track at constant velocity."""
        r = self.cfg.collision_radius
        ok = self.costmap.lookup(xy, self.costmap.distance, outside=np.inf).min(axis=1) >= r
        if self._tracks is not None and len(self._tracks):
            ok &= self._moving_clearance(xy, now, times) >= r
        return ok

    def _scores(
        self, traj: np.ndarray, ok: np.ndarray, near: np.ndarray, goal: np.ndarray, *, goal_latched: bool, at_end: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each rollout's cost against the local `goal` (inadmissible ones infinite), snapped to
        SCORE_RESOLUTION, and its point `forward_point_distance` ahead of its end.
        dwa_local_planner scores the path at the end and at that point and the goal at that
        point; `at_end`: path and goal both at the end (base_local_planner's
        TrajectoryPlanner); `goal_latched`: the goal at the end. Distances in costmap cells,
        as ROS counts them."""
        cfg, res = self.cfg, self.costmap.cfg.resolution
        xy = traj[..., :2]
        end = xy[:, -1]
        sin_h, cos_h = sincos(traj[:, -1, 2])
        front = end + cfg.forward_point_distance * np.column_stack([cos_h, sin_h])
        path_cost = distance_to_polyline(end, near) / res
        if goal_latched:
            align_cost = 0.0
            goal_cost = hypot(end[:, 0] - self.info.goal[0], end[:, 1] - self.info.goal[1]) / res
        elif at_end:
            align_cost = 0.0
            goal_cost = hypot(end[:, 0] - goal[0], end[:, 1] - goal[1]) / res
        else:
            align_cost = distance_to_polyline(front, near) / res
            goal_cost = hypot(front[:, 0] - goal[0], front[:, 1] - goal[1]) / res
        occ_cost = self.costmap.lookup(xy).max(axis=1)
        total = (
            cfg.path_distance_bias * (path_cost + align_cost)
            + cfg.goal_distance_bias * goal_cost
            + cfg.occdist_scale * occ_cost
        )
        total[~ok] = np.inf
        return snap_array(total, SCORE_RESOLUTION, out=total), front

    def _moving_clearance(self, xy: np.ndarray, now: float, times: np.ndarray) -> np.ndarray:
        """Smallest distance (N,) of each rollout (N, K, 2) from the tracks' surfaces, each
        track at constant velocity at the rollout point's time (`times` from now), its radius
        grown by its uncertainty then (`uncertainty_sigmas`)."""
        tracks = self._tracks.covering_circles()  # outlines as circles
        after = (now + times) - tracks.time  # (K,): the points' times after the tracks'
        return distance_to_tracks(xy[..., 0], xy[..., 1], after, tracks, self.cfg).min(axis=1)

    def _escape(self, obs: Observation) -> tuple[float, float]:
        """Nothing admissible: back up turning to the freer side, else rotate in place."""
        cfg = self.cfg
        angles = self.info.laser_angles
        left = obs.scan[angles > 0].mean()
        right = obs.scan[angles < 0].mean()
        turn = 1.0 if left >= right else -1.0
        ws = turn * np.linspace(0.0, cfg.max_vel_theta * 0.5, 5)
        traj = rollout(obs.pose, np.full(ws.shape, cfg.escape_vel), ws, self._times[self._times <= 1.0])
        dist = self.costmap.lookup(traj[..., :2], self.costmap.distance, outside=np.inf).min(axis=1)
        here = float(self.costmap.lookup(obs.pose[None, :2], self.costmap.distance, outside=np.inf)[0])
        k = int(np.argmax(dist))
        if dist[k] > here:
            self._last_plan = traj[k, :, :2]
            self._prev = np.array([cfg.escape_vel, ws[k]])
        else:
            self._last_plan = np.zeros((0, 2))
            self._prev = np.array([0.0, turn * cfg.max_vel_theta * 0.5])
        return float(self._prev[0]), float(self._prev[1])
