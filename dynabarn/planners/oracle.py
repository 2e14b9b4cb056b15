"""`oracle`: a privileged demonstrator that knows every obstacle's schedule.

Synthetic demonstrations where no person is available. It plans against the obstacles'
exact future positions (their schedules and the trial's clock offset: `obstacles.predict`),
which no real robot knows: recordings and datasets mark its episodes as synthetic.

Per tick it searches two-segment controls: (v1, w1) for `t1` seconds, then (v2, w2) for
`t2` seconds, on a grid of speeds and turn rates (all combinations, vectorised). Every
candidate is rolled out at `dt` and checked against the walls (exact box distances), the
static cylinders (a distance transform of the known map) and each moving obstacle at the
same future time; among the collision-free candidates it
takes the one whose end point has the lowest cost-to-go on the static Dijkstra field,
with a penalty for passing close to obstacles. With no collision-free candidate it takes
the one that stays clear longest.
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dynabarn.determinism import SCORE_RESOLUTION, hypot, sincos, snap_array
from dynabarn.interfaces import CheckedConfig, EpisodeInfo, Observation, ObstacleState, Planner, config_from_kwargs
from dynabarn.interfaces.planner import recorded_config
from dynabarn.perception.map_distance import MapDistance, grid_indices
from dynabarn.planners.global_planner import GlobalPlanner


@dataclass
class OracleConfig(CheckedConfig):
    v_samples: tuple = (-0.5, 0.0, 0.5, 1.0, 1.5, 2.0)
    """Forward speeds tried in each segment [m/s]."""
    w_samples: tuple = (-2.5, -1.2, -0.5, 0.0, 0.5, 1.2, 2.5)
    """Turn rates tried in each segment [rad/s]."""
    t1: float = 0.8
    """First segment [s] (re-planned every control period)."""
    t2: float = 1.6
    """Second segment [s]."""
    dt: float = 0.1
    """Rollout step [s]."""
    safety: float = 0.15
    """Clearance required beyond touching [m]."""
    comfort: float = 0.6
    """Clearance below which a candidate is penalised [m]."""
    clearance_weight: float = 3.0
    first_segment_weight: float = 0.25
    """Weight of the cost-to-go where the first segment ends, beside the end point's: of
    two candidates ending equally far, the one that makes its progress now wins (without
    it the oracle can wait forever in front of a passage, always planning to go later)."""
    static_safety: float = 0.03
    """Clearance required from static cylinders [m]: they are known exactly and do not
    move, and a mixed world's field only guarantees passages this much wider than the
    robot's circumscribed circle."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "v_samples": (-2.0, 5.0),
        "w_samples": (-10.0, 10.0),
        "t1": (0.05, 10.0),
        "t2": (0.0, 10.0),
        "dt": (0.01, 1.0),
        "safety": (0.0, 2.0),
        "comfort": (0.0, 5.0),
        "clearance_weight": (0.0, 1e6),
        "first_segment_weight": (0.0, 1e6),
        "static_safety": (0.0, 2.0),
    }
    """Accepted ranges (checked before a run)."""
    MAX_CANDIDATES: ClassVar[int] = 10_000
    """(v, w) pairs squared: two segments of every pair are rolled out each tick."""
    ORDERED: ClassVar[tuple[tuple[str, str], ...]] = (("dt", "t1"),)
    """A rollout step no longer than the first segment (`interfaces.planner.check_relations`)."""

    def check(self, what: str) -> None:
        """The candidate grid fits in memory (3,000 x 3,000 samples asked for 589 TiB)."""
        if (len(self.v_samples) * len(self.w_samples)) ** 2 > self.MAX_CANDIDATES:
            raise TypeError(f"{what}: too many candidates ((v samples x w samples)^2 > {self.MAX_CANDIDATES})")

    @classmethod
    def from_kwargs(cls, **kwargs) -> OracleConfig:
        return config_from_kwargs(cls, kwargs, "oracle")


@dataclass(frozen=True)
class _CandidateGrid:
    """What the search's rollouts take from the samples alone (read-only arrays, shared)."""

    v1: np.ndarray  # (N,) each candidate's two (v, w) commands
    w1: np.ndarray
    v2: np.ndarray
    w2: np.ndarray
    steps: np.ndarray  # (K,) rollout times after now [s]
    v: np.ndarray  # (K, N) each step's speed
    turned: np.ndarray  # (P,) distinct (turn so far, half a step's turn) pairs
    half_step: np.ndarray
    heading_of: np.ndarray  # (K * N,) each step's pair
    n_first: int
    per_first: int  # consecutive candidates sharing a first segment (the meshgrid's inner (v2, w2))


@functools.lru_cache(maxsize=8)
def _candidate_grid(v_samples: tuple, w_samples: tuple, t1: float, t2: float, dt: float) -> _CandidateGrid:
    """The (v1, w1, v2, w2) grid and its rollouts' constant parts, made once per configuration
    (every episode of a sweep makes a planner). A heading at mid-step is (yaw + turned) -
    half_step: the first segment's turn depends on w1 alone and the second's on (w1, w2), so
    of the 42,336 steps of the shipped grid only 589 pairs differ, and `_rollout` takes sine
    and cosine once per pair (the same expressions as per step, so the same bits)."""
    v = np.asarray(v_samples, dtype=float)
    w = np.asarray(w_samples, dtype=float)
    v1, w1, v2, w2 = (a.ravel() for a in np.meshgrid(v, w, v, w, indexing="ij"))
    n1, n2 = round(t1 / dt), round(t2 / dt)
    steps = np.arange(1, n1 + n2 + 1) * dt
    in_first = np.arange(1, n1 + n2 + 1) <= n1
    speed = np.where(in_first[:, None], v1[None, :], v2[None, :])  # (K, N)
    turn_rate = np.where(in_first[:, None], w1[None, :], w2[None, :])
    turned, half_step = np.cumsum(turn_rate * dt, axis=0), 0.5 * turn_rate * dt
    pairs, heading_of = np.unique(np.stack([turned.ravel(), half_step.ravel()]), axis=1, return_inverse=True)
    arrays = (v1, w1, v2, w2, steps, speed, pairs[0].copy(), pairs[1].copy(), heading_of.ravel())
    for a in arrays:
        a.flags.writeable = False
    return _CandidateGrid(*arrays, n_first=n1, per_first=len(v) * len(w))


RUNS_IN_SECOND = 2
"""Runs the second segment's steps are measured in (`_obstacle_clearance`): 1, 2, 4 and 8
gave the oracle 3.43, 3.30, 3.68 and 4.44 ms per call on the bench's worlds (each run's
fixed cost outgrows what its smaller box saves)."""
GOAL_REACH = 0.2
"""A rollout pose this close to the goal [m] reaches it (and beats any cost-to-go)."""


BOUND_SLACK = 1e-6
"""[m] added to every lower bound on a distance taken from the candidates' box: covers the
rounding of the box and of the distances themselves."""


@dataclass(frozen=True)
class Rollouts:
    """Every candidate's position at each step, steps major: x and y (K, N), contiguous.

    A step's reduction over the candidates (the boxes) and a candidate's over its steps
    (least clearance, blocked) then run along contiguous rows or as elementwise minima of
    rows; over the short inner axis of (N, K, 2), or along a strided one, the same
    reductions took 5 to 50 times as long (the candidates' boxes: 540 us against 14 us)."""

    x: np.ndarray
    y: np.ndarray

    def runs(self, k0: int, k1: int, every: int) -> Rollouts:
        """Steps k0..k1 of every `every`-th candidate."""
        return Rollouts(self.x[k0:k1, ::every], self.y[k0:k1, ::every])

    def path(self, candidate: int) -> np.ndarray:
        """(K, 2) one candidate's positions."""
        return np.column_stack([self.x[:, candidate], self.y[:, candidate]])


def _boxes(rollouts: Rollouts) -> tuple[np.ndarray, np.ndarray]:
    """Centre and half size (K, 2) of the box around every candidate's position at each step."""
    x, y = rollouts.x, rollouts.y
    lo = np.column_stack([x.min(axis=1), y.min(axis=1)])
    hi = np.column_stack([x.max(axis=1), y.max(axis=1)])
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


def _box_distance(box: tuple[np.ndarray, np.ndarray], centres: np.ndarray, halves=0.0) -> np.ndarray:
    """(K, n) distance at each step from the candidates' box (centre and half size, (K, 2)
    each) to n boxes of `centres` and half sizes `halves` ((K, n, 2) or (n, 2); 0: points):
    a lower bound on the distance from any candidate at that step to anything inside them."""
    centre, half = box
    gap = np.maximum(np.abs(centres - centre[:, None, :]) - half[:, None, :] - halves, 0.0)
    return hypot(gap[..., 0], gap[..., 1])


class OraclePlanner(Planner):
    """Privileged planner: time-aware search against the obstacles' known schedules."""

    name = "oracle"
    privileged = True
    config_class: ClassVar[type[OracleConfig]] = OracleConfig

    def __init__(self, **config) -> None:
        self.cfg = self.config_class.from_kwargs(**config)
        c = self.cfg
        grid = _candidate_grid(tuple(c.v_samples), tuple(c.w_samples), c.t1, c.t2, c.dt)
        self._v1, self._w1, self._v2, self._w2 = grid.v1, grid.w1, grid.v2, grid.w2
        self._steps, self._v = grid.steps, grid.v
        self._turned, self._half_step = grid.turned, grid.half_step
        self._n_first, self._per_first = grid.n_first, grid.per_first
        n1, k = grid.n_first, len(grid.steps)
        heading = grid.heading_of.reshape(grid.v.shape)
        self._first_heading = np.ascontiguousarray(heading[:n1, :: grid.per_first])
        self._second_heading = np.ascontiguousarray(heading[n1:])
        self._v_first = np.ascontiguousarray(grid.v[:n1, :: grid.per_first])
        self._v_second = np.ascontiguousarray(grid.v[n1:])
        cuts = np.linspace(n1, k, RUNS_IN_SECOND + 1).round().astype(int).tolist()
        self._runs = ((0, n1, grid.per_first), *((a, b, 1) for a, b in itertools.pairwise(cuts) if b > a))
        """Steps measured together: the shared first segment, then runs of the second (a
        run's candidates lie in a smaller box than all of them, so fewer obstacles are near)."""
        self._last: np.ndarray | None = None

    def command_set(self) -> np.ndarray:
        """Every (v, w) of the sample grid, v major (what a classifying student chooses among)."""
        v, w = np.meshgrid(np.asarray(self.cfg.v_samples, float), np.asarray(self.cfg.w_samples, float), indexing="ij")
        return np.stack([v.ravel(), w.ravel()], axis=1)

    def config(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in recorded_config(self.cfg).items()}

    def reset(self, info: EpisodeInfo) -> None:
        self.info = info
        self.radius = 0.5 * math.hypot(*info.footprint)
        # Its cost-to-go routes only through passages its own static check lets it through.
        self.global_planner = GlobalPlanner(
            info.walls,
            info.goal,
            inflation=self.radius,
            circles=info.static_obstacles,
            circle_inflation=self.radius + self.cfg.static_safety,
        )
        self._static = MapDistance(info.static_obstacles) if len(info.static_obstacles) else None
        self._last = None

    def debug(self) -> dict:
        return {"local_plan": self._last} if self._last is not None else {}

    def _rollout(self, pose: np.ndarray) -> Rollouts:
        """Positions of every two-segment candidate at each step. The first segment depends
        on (v1, w1) alone: it is rolled out once per pair and repeated, and the second
        continues each candidate's running sums from its end (a running sum is sequential,
        so the same bits as one sum over all steps)."""
        dt = self.cfg.dt
        sin_u, cos_u = sincos((pose[2] + self._turned) - self._half_step)  # the same bits on every CPU
        n1, every, pairs = self._n_first, self._per_first, len(self._v_first[0])
        out = []
        for start, trig in ((pose[0], cos_u), (pose[1], sin_u)):
            sums = np.empty(self._v.shape)  # (K, N): running sums of each step's move
            first = np.cumsum(self._v_first * trig[self._first_heading] * dt, axis=0)  # (n1, pairs)
            sums[:n1].reshape(n1, pairs, every)[...] = first[:, :, None]
            np.multiply(self._v_second * trig[self._second_heading], dt, out=sums[n1:])
            for k in range(n1, len(sums)):  # row by row: numpy's cumsum down the long axis took 5x as long
                sums[k] += sums[k - 1]
            sums += start
            out.append(sums)
        return Rollouts(*out)

    def _obstacle_clearance(
        self, rollouts: Rollouts, future: np.ndarray, radii: np.ndarray, box: tuple | None = None
    ) -> np.ndarray:
        """(K, N) clearance of every candidate pose from the obstacles `future` (K, n, 2) of
        radii (n,) or (K, n): the least distance beyond touching (inf without obstacles).

        Measured in runs of steps (`_runs`): the first segment's poses are those of the
        (v1, w1) pair alone, so each run of `_per_first` consecutive candidates shares them,
        bit for bit, and they are measured once and repeated. With the candidates' `box`,
        each run measures only the obstacles that can come within `comfort` of it (`_near`)."""
        per_step = radii.ndim == 2
        parts = []
        for k0, k1, every in self._runs:
            f, r = future[k0:k1], (radii[k0:k1] if per_step else radii)
            if box is not None:
                near = self._near((box[0][k0:k1], box[1][k0:k1]), f, r)
                f, r = f[:, near], r[..., near]
            run = rollouts.runs(k0, k1, every)
            part = self._clearance(run, f, r) if f.shape[1] else np.full(run.x.shape, np.inf)
            parts.append(np.repeat(part, every, axis=1) if every > 1 else part)
        return np.concatenate(parts, axis=0)

    def _clearance(self, rollouts: Rollouts, future: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """(K, N) least distance beyond touching from the candidates to obstacles (K, n, 2),
        one obstacle at a time into buffers of the candidates' shape, which stay in cache
        (the (n, K, N) array of every distance at once, broadcast from the obstacles' strided
        view, took 4 to 6 times as long for 3 to 10 obstacles)."""
        x, y = rollouts.x, rollouts.y
        fx, fy = np.ascontiguousarray(future[..., 0].T), np.ascontiguousarray(future[..., 1].T)  # (n, K)
        per_step = radii.ndim == 2
        dx, dy = np.empty_like(x), np.empty_like(y)
        least = np.full_like(x, np.inf)
        for j in range(len(fx)):
            np.subtract(x, fx[j, :, None], out=dx)
            np.subtract(y, fy[j, :, None], out=dy)
            dx *= dx
            dy *= dy
            dx += dy
            np.sqrt(dx, out=dx)  # determinism.hypot's operations, in place
            dx -= radii[:, j, None] if per_step else radii[j]
            np.minimum(least, dx, out=least)
        least -= self.radius
        return least

    def _near(self, box: tuple[np.ndarray, np.ndarray], future: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """(n,) which obstacles can come within `comfort` of some candidate: at each step,
        the distance from an obstacle to the box around every candidate's pose bounds its
        distance to each of them from below. The others change nothing a decision rests on
        while some candidate is safe (a clearance over `comfort` costs nothing and blocks
        nothing, and the least clearance below it is a near obstacle's or a wall's), so
        their distances are not computed; `act` computes them where it needs every one."""
        bound = _box_distance(box, future) - (radii[None, :] if radii.ndim == 1 else radii)
        return bound.min(axis=0) - self.radius <= self.cfg.comfort + BOUND_SLACK

    def _near_walls(self, box: tuple[np.ndarray, np.ndarray]) -> list:
        """The walls that can come within `comfort` of some candidate (as `_near`: the
        distance between a wall and the candidates' box at each step bounds it from below)."""
        walls = np.asarray(self.info.walls, dtype=float).reshape(-1, 4)
        bound = _box_distance(box, walls[:, :2], walls[:, 2:] / 2).min(axis=0)
        near = bound - self.radius <= self.cfg.comfort + BOUND_SLACK
        return [wall for wall, keep in zip(self.info.walls, near, strict=True) if keep]

    def _wall_distance(self, rollouts: Rollouts, walls) -> np.ndarray:
        """(K, N) distance from each candidate's position to the nearest of `walls`."""
        d = np.full(rollouts.x.shape, np.inf)
        for cx, cy, sx, sy in walls:
            dx = np.maximum(np.abs(rollouts.x - cx) - sx / 2, 0.0)
            dy = np.maximum(np.abs(rollouts.y - cy) - sy / 2, 0.0)
            d = np.minimum(d, hypot(dx, dy))
        return d

    def _cost_to_go(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        f = self.global_planner.field
        res = self.global_planner.resolution
        cost = f.cost[grid_indices(x, y, res, f.nx, f.ny)]
        # Unreachable cells (inside inflated walls): fall back to the straight-line distance.
        straight = hypot(x - self.info.goal[0], y - self.info.goal[1]) + 5.0
        return np.where(np.isfinite(cost), cost, straight)

    def obstacle_future(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        """Where the moving obstacles will be at the rollout times `obs.time + self._steps`:
        centres (K, n, 2) and the radius to keep clear of, (n,) or (K, n). Here: their exact
        future, from the schedules; subclasses predict it from less."""
        state = self._true_state(obs)
        return state.predict(obs.time + self._steps), state.radii

    def _true_state(self, obs: Observation) -> ObstacleState:
        if obs.obstacles is None:
            raise RuntimeError(f"{self.name} needs privileged observations (Planner.privileged)")
        return obs.obstacles

    def act(self, obs: Observation) -> tuple[float, float]:
        c = self.cfg
        rollouts = self._rollout(obs.pose)
        x, y = rollouts.x, rollouts.y  # (K, N)
        future, radii = self.obstacle_future(obs)  # (K, n, 2), (n,) or (K, n)
        box = _boxes(rollouts)
        walls = self._wall_distance(rollouts, self._near_walls(box)) - self.radius
        clear = np.minimum(self._obstacle_clearance(rollouts, future, radii, box), walls)
        min_clear = np.minimum.reduce(clear, axis=0)
        blocked = clear <= c.safety  # (K, N)
        static_ok = np.ones(x.shape[1], dtype=bool)
        if self._static is not None:  # static cylinders: known exactly, so a smaller margin
            static_blocked = self._static.at(x, y) - self.radius <= c.static_safety
            static_ok = ~np.logical_or.reduce(static_blocked, axis=0)
            blocked |= static_blocked
        ok = ~np.logical_or.reduce(blocked, axis=0)
        first_end = self._n_first - 1
        cost = (
            self._cost_to_go(x[-1], y[-1])
            + c.first_segment_weight * self._cost_to_go(x[first_end], y[first_end])
            + c.clearance_weight * np.maximum(0.0, c.comfort - min_clear)
        )
        # Reaching the goal beats any cost-to-go; reaching it sooner beats later. (Measured
        # only where the candidates' box comes within reach of it.)
        goal = obs.goal_in_world
        if _box_distance(box, goal[None, :2]).min() < GOAL_REACH + BOUND_SLACK:
            at_goal = hypot(x - goal[0], y - goal[1]) < GOAL_REACH
            cost = np.where(np.logical_or.reduce(at_goal, axis=0), -10.0 + 0.01 * np.argmax(at_goal, axis=0), cost)
        if ok.any():
            cost = np.where(ok, cost, np.inf)
            # Ties in exact arithmetic stay ties on every CPU; the first candidate wins.
            best = int(np.argmin(snap_array(cost, SCORE_RESOLUTION, out=cost)))
        else:
            # Nothing is safe for the whole horizon: stay clear for as long as possible, and
            # never run into a static cylinder to get away from a mover if avoidable. Here
            # every clearance counts, the far obstacles' too.
            # (Rare: these ticks pay for measuring everything.)
            walls = self._wall_distance(rollouts, self.info.walls) - self.radius
            clear = np.minimum(self._obstacle_clearance(rollouts, future, radii), walls)
            min_clear = np.minimum.reduce(clear, axis=0)
            blocked = clear <= c.safety
            if self._static is not None:
                blocked |= static_blocked
            first_hit = np.where(blocked, np.arange(clear.shape[0])[:, None], clear.shape[0]).min(axis=0)
            best = int(np.argmax(snap_array(static_ok * 1e6 + first_hit * 1000.0 + min_clear, SCORE_RESOLUTION)))
        self._last = rollouts.path(best)
        return float(self._v1[best]), float(self._w1[best])


class PresentStateOraclePlanner(OraclePlanner):
    """`oracle_present`: the oracle's search told only the obstacles' true present positions
    and velocities, extrapolated at constant velocity: what a perfect tracker would give.
    Privileged (a rung of the ladder from blind to all-knowing, not a robot's planner)."""

    name = "oracle_present"

    def obstacle_future(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        state = self._true_state(obs)
        return state.positions[None] + state.velocities[None] * self._steps[:, None, None], state.radii
