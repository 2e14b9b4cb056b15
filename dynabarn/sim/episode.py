"""One episode's state, advanced one control period at a time."""

from __future__ import annotations

import math
import time
from functools import cached_property

import mujoco
import numpy as np

from dynabarn.determinism import (
    COMMAND_RESOLUTION,
    RECORD_RESOLUTION,
    snap,
)
from dynabarn.errors import DynabarnError
from dynabarn.interfaces.events import Tick
from dynabarn.interfaces.observation import Observation, ObstacleState
from dynabarn.metrics import NON_FINITE_COMMAND, Outcome
from dynabarn.protocol import EvalProtocol
from dynabarn.robot import JACKAL, to_robot_frame
from dynabarn.sim.behaviors import ReactiveObstacles
from dynabarn.sim.simulation import Simulation
from dynabarn.sim.tick import TickFacts, tick_from
from dynabarn.sim.track_scoring import MIN_BEAMS, TrackScorer, beams_per_obstacle
from dynabarn.sim_config import draw_clock_offset, episode_rng
from dynabarn.worlds.schedule import SchedulePlayer

FAR_FROM_GOAL = 1.0
"""[m] beyond the goal region: a robot that ends a control period this far out was never
inside it during the period (it covers at most 0.2 m at 2 m/s), so the period's checks
reduce to the clock's."""
MAX_PHYSICS_STEPS = 5_000_000
"""Longest episode in physics steps (its pose buffer is 120 MB); 100 s at 5 ms is 40,000."""


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
        self.rng = episode_rng(seed)
        self.clock_offset = draw_clock_offset(self.rng)
        self.player = SchedulePlayer(sim.world, clock_offset=self.clock_offset)
        self.info = sim.episode_info(protocol, seed)
        self.dt = config.dt
        self.k = config.steps_per_tick
        self.period = config.control_period
        max_steps = math.ceil(protocol.longest_episode / self.dt) + 2 * self.k
        if max_steps > MAX_PHYSICS_STEPS:  # the per-step buffers below would not fit in memory
            raise DynabarnError(
                f"protocol {protocol.name!r} with dt {self.dt:g} s allows {max_steps:,} physics steps; "
                f"at most {MAX_PHYSICS_STEPS:,} (shorten time_limit or enlarge dt)"
            )
        self.poses = np.zeros((max_steps + 1, 3))  # robot pose after every physics step
        n_ticks_max = max_steps // self.k + 2
        self.tick_v = np.zeros(n_ticks_max)
        self.tick_w = np.zeros(n_ticks_max)
        self.tick_w_cmd = np.zeros(n_ticks_max)
        self.planner_ms = np.zeros(n_ticks_max)
        self.step_offsets = np.arange(self.k) * self.dt
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
        self.track_scorer: TrackScorer | None = None
        """Tracking quality of a planner with a tracker (`score_tracks`), else None."""
        # Reactive obstacles run on their own clocks (a yielding one pauses its schedule);
        # scripted-only worlds keep the exact global clock.
        self.reactive: ReactiveObstacles | None = None
        if any(o.reactive for o in sim.world.obstacles):
            self.reactive = ReactiveObstacles(
                sim.world.obstacles,
                self.player,
                sim.bounding_radii,
                period=self.period,
                step_offsets=self.step_offsets,
                max_steps=max_steps,
            )

    @property
    def time(self) -> float:
        return self.step * self.dt

    def observe(self) -> Observation:
        """Place the obstacles for now, cast the scan, and return what a planner sees."""
        self.place_obstacles()
        sim = self.sim
        return self.observe_ranges(sim.laser.cast(sim.model, sim.data, float(sim.data.qpos[2])))

    @property
    def observation(self) -> Observation:
        """The last observation made (`observe`, `observe_scan`, `observe_ranges`)."""
        return self._obs

    def period_times(self) -> np.ndarray:
        """The times [s] of this control period's physics steps (what the schedules are read at)."""
        return self.time + self.step_offsets

    @property
    def obstacle_centres(self) -> np.ndarray:
        """(n, 2) the obstacles where `place_obstacles` put them."""
        return self._batch_xy[0]

    def place_obstacles(self, schedule: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """The obstacles of this control period (all its physics steps at once), placed for
        now, with the kinematics updated: what a scan is cast against. `schedule`: their
        positions and velocities at `period_times()` when a batch of worlds evaluated them."""
        sim = self.sim
        if self.reactive is not None:
            self._batch_xy, self._batch_vel = self.reactive.batch(sim.data.qpos[:2])
        elif schedule is not None:
            self._batch_xy, self._batch_vel = schedule
        else:
            self._batch_xy, self._batch_vel = self.player.positions_at(self.period_times())
        sim.set_obstacles(self._batch_xy[0])
        mujoco.mj_kinematics(sim.model, sim.data)

    def observe_ranges(self, ranges: np.ndarray) -> Observation:
        """The observation from noise-free ranges cast after `place_obstacles` (the laser's
        noise drawn from this episode's generator, then the 1 mm grid)."""
        return self.observe_scan(self.sim.laser.noisy(ranges, self.rng))

    def observe_scan(self, scan: np.ndarray) -> Observation:
        """The observation around a finished scan (`Laser.noisy` of this episode's ranges,
        drawn from this episode's generator: a batch of worlds draws them together)."""
        sim = self.sim
        t = self.time
        qpos, qvel = sim.data.qpos, sim.data.qvel
        pose = qpos[:3].copy()
        c, s = math.cos(pose[2]), math.sin(pose[2])
        velocity = np.array([c * qvel[0] + s * qvel[1], qvel[2]])
        privileged = None
        if self.privileged:
            privileged = ObstacleState(
                positions=self._batch_xy[0].copy(),
                velocities=self._batch_vel[0].copy(),
                radii=sim.bounding_radii.copy(),
                predict=_constant_velocity(t, self._batch_xy[0], self._batch_vel[0])
                if self.reactive is not None
                else _predictor(self.player),
            )
        self._obs = Observation(
            time=t,
            scan=scan,
            pose=pose,
            velocity=velocity,
            goal_in_robot=to_robot_frame(sim.goal[None], pose)[0],
            goal_in_world=sim.goal.copy(),
            obstacles=privileged,
        )
        return self._obs

    def score_tracks(self, tracks):
        """Score the planner's tracks for the last observation against the truth (None: the
        planner has none this tick); returns them."""
        if tracks is None:
            return None
        sim = self.sim
        n = len(sim.radii)
        if self.track_scorer is None:
            self.track_scorer = TrackScorer(n)
        in_view = beams_per_obstacle(sim.laser.geom_ids, sim.obstacle_of_geom, n) >= MIN_BEAMS
        self.track_scorer.add(tracks, self._batch_xy[0], self._batch_vel[0], in_view)
        return tracks

    def end(self, outcome: Outcome, reason: str) -> None:
        self.outcome, self.reason = outcome, reason

    def apply(self, raw_v: float, raw_w: float) -> Outcome | None:
        """Limit the command, then run one control period of physics; the outcome if it ended."""
        if not (math.isfinite(raw_v) and math.isfinite(raw_w)):
            self.end(Outcome.ERROR, f"{NON_FINITE_COMMAND} ({raw_v}, {raw_w})")
            return self.outcome
        sim, cfg, p = self.sim, self.sim.config, JACKAL
        data = sim.data
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

        batch_xy, step, t_start = self._batch_xy, self.step, self.t_start
        if self.reactive is not None:  # what the obstacles really did, for the clearance metric
            log = self.reactive.log
            n_log = min(self.k, len(log) - step)
            log[step : step + n_log] = batch_xy[:n_log]
        # The physics steps first (MuJoCo stops only for a contact), then the protocol's
        # checks of every step at once, in the order a step-by-step loop makes them
        # (contact, clock start, goal, time limit): the same outcome at the same step.
        first = step + 1
        m, contact = sim.physics.run(batch_xy, self.poses[first : first + self.k])
        outcome, step, t_start = self._judge(first, m, contact, t_start)
        self.step, self.t_start, self.outcome = step, t_start, outcome
        return outcome

    def _judge(self, first: int, m: int, contact: bool, t_start: float | None):
        """The protocol's checks of physics steps first..first+m-1 at once, in the order a
        step-by-step loop makes them (contact, clock start, goal, time limit): (outcome,
        the step it ended at or the last one, the clock's start)."""
        protocol, dt, limit = self.protocol, self.dt, self.protocol.time_limit
        goal = (float(self.sim.goal[0]), float(self.sim.goal[1]))
        last = self.poses[first + m - 1]
        xy = self.poses[first : first + m, :2]
        if (
            not contact
            and (first + m - 1) * dt - (0.0 if t_start is None else t_start) < limit
            and math.hypot(last[0] - goal[0], last[1] - goal[1])
            > math.sqrt(2) * protocol.goal_tolerance + FAR_FROM_GOAL
            and (t_start is not None or not protocol.timer_started(xy[:, 0], xy[:, 1]).any())
        ):
            # The common period: nothing can have happened (the clock running, or not yet
            # started by any of the period's poses, as while a robot waits at its spawn).
            return None, first + m - 1, t_start
        ts = np.arange(first, first + m) * dt
        begun = np.zeros(0, dtype=np.int64)
        if t_start is None:
            started = protocol.timer_started(xy[:, 0], xy[:, 1])
            if contact:
                started[-1] = False  # the loop ends at a contact before the clock is looked at
            begun = np.flatnonzero(started)
            clock0 = np.zeros(m)
            if len(begun):
                clock0[begun[0] :] = float(ts[begun[0]])
        else:
            clock0 = np.full(m, t_start)
        ended = protocol.reached(xy[:, 0], xy[:, 1], goal)
        event = ended | (ts - clock0 >= limit)
        if contact:
            event[-1] = False
        hits = np.flatnonzero(event)
        if len(hits):
            j = int(hits[0])
            if ended[j]:
                outcome, self.reason = Outcome.SUCCESS, "reached the goal"
            else:
                outcome, self.reason = Outcome.TIMEOUT, f"time limit {limit:g} s"
        else:
            j = m - 1
            outcome = None
            if contact:
                self.reason = f"hit {_contact_partner(self.sim.model, self.sim.data, self.sim.robot_geoms)}"
                outcome = Outcome.COLLISION
        if t_start is None and len(begun) and begun[0] <= j:  # the clock as it stood when the loop ended
            t_start = float(ts[begun[0]])
        return outcome, first + j, t_start

    def tick_record(self, debug: dict, tracks=None) -> Tick:
        """The last observation and command (as received, on its grid), for observers."""
        t, scan, pose, velocity, command, raw, obstacles, planner_ms, clearance = self.period_numbers()
        return tick_from(
            t,
            scan,
            pose,
            velocity,
            command.copy(),
            np.array(raw, dtype=np.float64),
            obstacles.copy(),
            planner_ms,
            debug,
            tracks,
            self.tick_facts,
            clearance,
        )

    def period_numbers(self) -> tuple:
        """This period's numbers a Tick is made of (`sim.tick.tick_from`), as
        references: time, scan, pose, velocity, command, raw command, obstacles, planner
        ms, and the clearance where the world's shapes need the simulation for it."""
        obs, sim = self._obs, self.sim
        clearance = None
        if sim.shaped:
            clearance = snap(float(sim.clearance(obs.pose[None], self._batch_xy[:1])[0]), RECORD_RESOLUTION)
        planner_ms = float(self.planner_ms[self.n_ticks - 1]) if self.n_ticks else 0.0
        return (
            obs.time,
            obs.scan,
            obs.pose,
            obs.velocity,
            self.prev_cmd,
            self.raw_command,
            self._batch_xy[0],
            planner_ms,
            clearance,
        )

    @cached_property
    def _pose_every(self) -> int:
        return self.sim.config.pose_every

    @cached_property
    def tick_facts(self) -> TickFacts:
        sim = self.sim
        return TickFacts(laser_offset=self.info.laser_offset, radii=sim.radii, goal=sim.goal)

    def poses_between(self, first: int) -> tuple[np.ndarray, np.ndarray]:
        """Times and poses at the pose rate after physics step `first` up to now (the last
        pose always included once the episode has ended)."""
        idx = self.pose_steps(first, self.step, self.outcome is not None)
        every = self._pose_every
        if len(idx) and idx[-1] % every == 0:  # all on the grid: the same rows sliced, not gathered
            return idx * self.dt, self.poses[idx[0] : idx[-1] + 1 : every].copy()
        return idx * self.dt, self.poses[idx]

    def pose_steps(self, first: int, last: int, ended: bool) -> np.ndarray:
        """The physics steps (int64) whose poses are recorded for the period from step `first`
        to `last`: the multiples of the pose interval after `first` (from 0 for the first
        period), and `last` itself when the episode ended there off the grid."""
        every = self._pose_every
        first_idx = 0 if first == 0 else first + every - first % every
        idx = np.arange(first_idx, last + 1, every)
        if last % every and ended:
            idx = np.append(idx, last)
        return idx


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


def _contact_partner(model: mujoco.MjModel, data: mujoco.MjData, robot_geoms: set[int]) -> str:
    con = data.contact[0]
    g1, g2 = int(con.geom[0]), int(con.geom[1])
    other = g2 if g1 in robot_geoms else g1
    return model.geom(other).name or f"geom {other}"
