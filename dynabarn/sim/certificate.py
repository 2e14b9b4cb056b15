"""A world's solvability certificate: a search in space-time against the exact schedules.

Whether a world can be solved at all decides what a planner's failure there means. This
module answers it constructively, for one world and one trial (its clock offset): a
time-expanded search over the Jackal's own motions either returns a witness, a command
for every control tick that drives the robot from its spawn into the goal region without
touching anything, or says that none exists at its resolution.

The search (`certify`):
- States are poses with the last command (x, y, yaw, v, w) at control ticks. Each tick
  every state tries every command of a fixed set (`CertificateConfig.speeds` x
  `turn_rates`), limited as the runner limits it (the command space, the acceleration
  limits per tick); the pose is integrated over the tick with the actuator's first-order
  lag (`JackalParams.velocity_gain`) at `substeps` points.
- Safety: the robot is the disc around its footprint (radius: the footprint's farthest
  corner), each obstacle the disc around its shape; with `footprint`, the static field is
  checked against the Jackal's own rectangle at its heading instead
  (`certificate_occupancy`). At every substep point the gap between
  the discs must be at least the most they can close in half a substep (the robot's top
  speed plus the obstacles' `SchedulePlayer.max_speed`), a whole substep where a looping
  schedule jumps back, plus the occupancy grid's lookup error and a tracking margin for
  the replay. So the continuous motion between the points is collision-free too.
- The obstacles and the static geometry are stamped into occupancy grids (`grid` metres)
  for the tick's substep times; states look their points up.
- Pruning: of the states that end a tick in the same cell (`cell` metres, `heading_bins`
  headings), the first is kept. That bounds the work; it can lose a solution, which is
  what "at its resolution" means. The search is breadth-first in time, so the first
  state to reach the goal gives the earliest arrival at this resolution.
- Goal guidance (`beam`, version 4): of those, at most `beam` states are kept per tick,
  the nearest the goal along the static map (`Occupancy.cost_to_go`: a grid Dijkstra
  through the cells the robot can stand in). In a static field the breadth-first frontier
  fills every cell the robot can reach and runs out of any budget long before the goal
  (the committed tiers' searches stopped at t = 9-13 s); the beam spends the work where
  the goal is. It keeps the search's soundness (a witness is still checked at every
  substep and replayed in MuJoCo) and gives up its completeness: without a witness it
  makes no claim, as a spent budget does not.
- Clock: the protocol's limit is counted from t = 0 (it starts at the first 0.1 m of
  motion in the episode): a certificate holds under either reading.

The witness is replayed in MuJoCo by `dynabarn.sim.witness` (a tracking controller
around its commands): only a replay that reaches the goal without contact certifies.
Every number is computed with IEEE operations or snapped (`dynabarn.determinism`), so the
same world gives the same certificate on every machine.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass
from typing import ClassVar

import numpy as np

from dynabarn.determinism import STATE_RESOLUTION, exp, sincos, snap_array
from dynabarn.protocol import EvalProtocol
from dynabarn.robot import JACKAL
from dynabarn.sim.certificate_occupancy import ROBOT_RADIUS, Occupancy
from dynabarn.sim_config import SimConfig
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import SCRIPTED, WorldSpec

_NOBODY = np.iinfo(np.int64).max
"""An unclaimed key in `certify`'s table of pruning cells."""
__all__ = ["ROBOT_RADIUS", "Certificate", "CertificateConfig", "Witness", "certify"]


@dataclass(frozen=True)
class CertificateConfig:
    """The search's resolution (recorded with every certificate)."""

    cell: float = 0.2
    """[m] Pruning cell: one state per cell and heading bin per tick."""
    heading_bins: int = 8
    substeps: int = 4
    """Collision checks per control tick."""
    grid: float = 0.05
    """[m] Occupancy grid the obstacles are stamped into."""
    tracking_margin: float = 0.05
    """[m] Room for the replay's tracking error (the replay checks it)."""
    speeds: tuple[float, ...] = (2.0, 1.5, 1.0, 0.5, 0.0, -0.5)
    """[m/s] Forward speeds tried each tick (fastest first: first kept in a cell)."""
    turn_rates: tuple[float, ...] = (0.0, 1.5, -1.5, 3.0, -3.0)
    """[rad/s] Yaw rates tried each tick."""
    footprint: bool = False
    """Check the Jackal's own rectangle, at its heading, against the static field (a
    configuration-space grid per heading bin), not the disc around it: passages the robot
    drives through lengthwise but its disc does not fit are searched too (version 3).
    Moving obstacles and walls are always checked against the disc."""
    footprint_headings: int = 64
    """Heading bins of the footprint's grids (each grown by what a half bin's turn sweeps)."""
    beam: int = 0
    """States kept per tick, the nearest the goal along the static map (0: every state
    the pruning cells keep, breadth-first; version 4 when set)."""
    VERSION: ClassVar[int] = 2
    """Bumped whenever the search changes what it certifies (2: the goal region shrunk by
    the tracking margin; 3: `footprint`; 4: `beam`. Each records its own version and keeps
    the earlier versions' certificates reproducible under their own resolution)."""

    @property
    def version(self) -> int:
        return 4 if self.beam else 3 if self.footprint else self.VERSION

    def to_dict(self) -> dict:
        d = asdict(self)
        if not self.beam:  # version 2's and 3's records, as they were written
            del d["beam"]
        if not self.footprint:
            del d["footprint"], d["footprint_headings"]
        return {"version": self.version, **d}

    @classmethod
    def from_dict(cls, d: dict) -> CertificateConfig:
        """The resolution an index records (`to_dict`): every field it names, the rest as
        the versions before them searched."""
        known = {f.name for f in dataclasses.fields(cls)}
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items() if k in known}
        config = cls(**values)
        if "version" in d and d["version"] != config.version:
            raise ValueError(
                f"resolution version {d['version']!r} does not match its fields (version {config.version})"
            )
        return config


@dataclass(frozen=True)
class Witness:
    """A certified way through: the command of every tick and the poses it gives."""

    period: float
    commands: np.ndarray
    """(K, 2) v [m/s], w [rad/s] for ticks 0..K-1."""
    poses: np.ndarray
    """(K + 1, 3) the search's poses at the ticks' starts (and the last one's end)."""
    arrival: float
    """[s] When the search's robot enters the goal region."""


@dataclass(frozen=True)
class Certificate:
    """The search's answer for one world and clock offset."""

    certified: bool
    reason: str
    clock_offset: float
    arrival: float | None = None
    """[s] The witness's arrival (None without a witness)."""
    expanded: int = 0
    """States expanded: the search's work."""
    witness: Witness | None = None

    def to_dict(self) -> dict:
        d = {"certified": self.certified, "reason": self.reason, "clock_offset": self.clock_offset}
        if self.arrival is not None:
            d["arrival"] = self.arrival
        return d


class _Motion:
    """One control tick of the Jackal: the runner's command limits, then the actuator's
    first-order lag, integrated at the substep points (IEEE operations only).

    A tick's motion in the robot's own frame depends only on the last command and the
    new one, a few dozen pairs: `table` integrates those once and every state composes
    them with its pose (one rotation), instead of each state integrating alone."""

    def __init__(self, config: CertificateConfig, sim: SimConfig) -> None:
        self.period = sim.control_period
        self.substeps = config.substeps
        self.ds = self.period / config.substeps
        self.dv, self.dw = sim.max_linear_accel * self.period, sim.max_angular_accel * self.period
        gain = JACKAL.velocity_gain
        edges = exp(-gain * self.ds * np.arange(config.substeps + 1))  # the same bits on every machine
        # The lagging velocity's mean over substep j is c + (prev - c) * lag[j].
        self.lag = np.array([float(x) for x in (edges[:-1] - edges[1:]) / (gain * self.ds)])
        v, w = np.meshgrid(np.array(config.speeds), np.array(config.turn_rates), indexing="ij")
        self.v_cmd = np.clip(v.ravel(), JACKAL.v_min, JACKAL.v_max)
        self.w_cmd = np.clip(w.ravel(), -JACKAL.w_max, JACKAL.w_max)

    def table(self, v0: np.ndarray, w0: np.ndarray):
        """For last commands v0 (A,) and w0 (B,): the applied commands v, w (A, B, P) of every
        primitive, and the displacement along and across the start heading and the turn
        after each substep, (A, B, P, substeps) each."""
        v = np.minimum(np.maximum(self.v_cmd, v0[:, None] - self.dv), v0[:, None] + self.dv)[:, None, :]
        w = np.minimum(np.maximum(self.w_cmd, w0[:, None] - self.dw), w0[:, None] + self.dw)[None, :, :]
        vm = v[..., None] + (v0[:, None, None, None] - v[..., None]) * self.lag  # (A, 1, P, S)
        wm = w[..., None] + (w0[None, :, None, None] - w[..., None]) * self.lag  # (1, B, P, S)
        turn = np.cumsum(wm * self.ds, axis=-1)
        s, c = sincos(turn - 0.5 * wm * self.ds)  # the heading at each substep's middle
        along = np.cumsum(vm * self.ds * c, axis=-1)
        across = np.cumsum(vm * self.ds * s, axis=-1)
        shape = (len(v0), len(w0), len(self.v_cmd), self.substeps)
        return (
            np.broadcast_to(v, shape[:3]),
            np.broadcast_to(w, shape[:3]),
            along,
            across,
            np.broadcast_to(turn, shape),
        )

    def advance(self, x, y, th, v0, w0, prim, parent):
        """Every candidate (state `parent`, primitive `prim`): the applied commands, and the
        positions (substeps, C) and heading (substeps, C) after each substep."""
        uv, iv = np.unique(v0, return_inverse=True)
        uw, iw = np.unique(w0, return_inverse=True)
        v, w, along, across, turn = self.table(uv, uw)
        n_prim = len(self.v_cmd)
        code = (iv[parent] * len(uw) + iw[parent]) * n_prim + prim  # into the tables' (A, B, P) cells
        rows = (self.substeps, -1)
        a = np.take(np.moveaxis(along, -1, 0).reshape(rows), code, axis=1)  # (substeps, C)
        b = np.take(np.moveaxis(across, -1, 0).reshape(rows), code, axis=1)
        s, c = sincos(th)
        s, c = s[parent], c[parent]
        xs = x[parent] + c * a - s * b
        ys = y[parent] + s * a + c * b
        ths = th[parent] + np.take(np.moveaxis(turn, -1, 0).reshape(rows), code, axis=1)
        return v.ravel()[code], w.ravel()[code], xs, ys, ths


def certify(
    world: WorldSpec,
    protocol: EvalProtocol,
    *,
    clock_offset: float,
    sim: SimConfig | None = None,
    config: CertificateConfig | None = None,
    budget: int | None = None,
) -> Certificate:
    """The certificate of `world` under `protocol` for obstacle clocks shifted by `clock_offset`.

    `budget` bounds the work: once the search has expanded that many states without a
    witness it stops and says so (no claim either way; `bench.certify` then tries the exact
    oracle's episode). None: the search runs to the time limit."""
    sim, config = sim or SimConfig(), config or CertificateConfig()
    reactive = sorted({o.behavior for o in world.obstacles if o.behavior != SCRIPTED})
    if reactive:
        return Certificate(False, f"reactive obstacles ({', '.join(reactive)}) have no schedule", clock_offset)
    player = SchedulePlayer(world, clock_offset=clock_offset)
    occupancy = Occupancy.of_search(world, player, protocol, config)
    if not math.isfinite(occupancy.obstacle_speed):
        return Certificate(False, "a schedule has a segment without duration (unbounded speed)", clock_offset)
    motion = _Motion(config, sim)
    closing = max(JACKAL.v_max, -JACKAL.v_min) + occupancy.obstacle_speed
    goal = (float(world.layout.goal[0]), float(world.layout.goal[1]))
    # The witness must reach the goal region shrunk by the tracking margin: the robot that
    # drives it, within that margin of it, is then inside the region at the same time.
    inner = dataclasses.replace(protocol, goal_tolerance=max(protocol.goal_tolerance - config.tracking_margin, 1e-3))
    spawn = tuple(float(v) for v in protocol.spawn)
    occupancy.stamp(np.zeros(1), np.array([0.5 * closing * motion.ds]))
    if not occupancy.free(0, np.array([spawn[0]]), np.array([spawn[1]]), np.array([spawn[2]]))[0]:
        return Certificate(
            False, "the spawn is within the search's margin of an obstacle or wall at the start", clock_offset
        )
    state = [np.array([v]) for v in (*spawn, 0.0, 0.0)]  # x, y, yaw, last v, last w
    n_prim = len(motion.v_cmd)
    history: list[tuple[np.ndarray, np.ndarray]] = []  # per tick: (parent state, primitive) of the kept states
    expanded = 0
    n_ticks = math.ceil(protocol.time_limit / motion.period - 1e-9)
    cells_x = math.ceil(occupancy.nx * config.grid / config.cell) + 1
    cells_y = math.ceil(occupancy.ny * config.grid / config.cell) + 1
    owner = np.full(cells_x * cells_y * config.heading_bins, _NOBODY, dtype=np.int64)
    cost_to_go = occupancy.cost_to_go(goal) if config.beam else None
    for tick in range(n_ticks):
        t0 = tick * motion.period
        times = t0 + motion.ds * np.arange(1, config.substeps + 1)
        wraps = player.clock_wraps(np.concatenate([[t0], times[:-1]]), times)
        after = np.append(wraps[1:], player.clock_wraps(times[-1:], times[-1:] + motion.ds))
        margins = 0.5 * closing * motion.ds * np.where(wraps | after, 2.0, 1.0)
        occupancy.stamp(times, margins)
        # Primitive-major: candidates are ordered fastest primitive first, then by state,
        # and the first of a kind wins everywhere below (one deterministic choice).
        n = len(state[0])
        parent, prim = np.tile(np.arange(n), n_prim), np.repeat(np.arange(n_prim), n)
        expanded += len(parent)
        v, w, xs, ys, ths = motion.advance(*state, prim, parent)
        ok = np.ones(len(parent), dtype=bool)
        for j in range(config.substeps):
            ok &= occupancy.free(j, xs[j], ys[j], ths[j])
            arrived = np.flatnonzero(ok & inner.reached(xs[j], ys[j], goal))
            if len(arrived):
                history.append((parent[arrived[:1]], prim[arrived[:1]]))
                witness = _witness(history, motion, spawn, float(t0 + (j + 1) * motion.ds))
                return Certificate(True, "witness found", clock_offset, witness.arrival, expanded, witness)
        keep = np.flatnonzero(ok)
        if len(keep) == 0:
            return Certificate(False, f"no collision-free motion beyond t = {t0:g} s", clock_offset, None, expanded)
        if budget is not None and expanded >= budget:
            reason = f"the search's budget of {budget} states ran out at t = {t0 + motion.period:g} s"
            return Certificate(False, reason, clock_offset, None, expanded)
        x, y, th = xs[-1, keep], ys[-1, keep], ths[-1, keep]
        first = _first_per_cell(x, y, th, owner, occupancy, config, cells_x, cost_to_go)
        chosen = keep[first]
        history.append((parent[chosen], prim[chosen]))
        state = [snap_array(a[first], STATE_RESOLUTION) for a in (x, y, th)] + [v[chosen], w[chosen]]
    reason = f"no witness within the time limit {protocol.time_limit:g} s"
    if config.beam:
        reason += f" (goal-guided: {config.beam} states a tick, no claim that none exists)"
    return Certificate(False, reason, clock_offset, None, expanded)


def _nearest_the_goal(first: np.ndarray, x, y, cost_to_go: np.ndarray, occupancy: Occupancy, beam: int) -> np.ndarray:
    """Of the states `first` (indices into x, y, in order), the `beam` nearest the goal
    along the static map, in their order (equal distances: the earlier state first)."""
    cost = occupancy.lookup(cost_to_go, x[first], y[first])
    nearest = np.argsort(cost, kind="stable")[:beam]
    return first[np.sort(nearest)]


def _first_per_cell(
    x, y, th, owner: np.ndarray, occupancy: Occupancy, config: CertificateConfig, cells_x: int, cost_to_go=None
):
    """The indices of the first state in each pruning cell and heading bin, in order. The
    least index per key is scattered into `owner`, a table of every key (no sort of the
    candidates), which is left unclaimed again. With `cost_to_go` (`config.beam`), of
    those the `beam` nearest the goal."""
    ix = np.floor((x - occupancy.x0) / config.cell).astype(np.int64)
    iy = np.floor((y - occupancy.y0) / config.cell).astype(np.int64)
    hb = np.floor(np.mod(th, 2 * math.pi) * (config.heading_bins / (2 * math.pi))).astype(np.int64)
    key = (iy * cells_x + ix) * config.heading_bins + np.minimum(hb, config.heading_bins - 1)
    np.minimum.at(owner, key, np.arange(len(key)))
    first = owner[key]
    first = first[first == np.arange(len(key))]
    owner[key] = _NOBODY
    if cost_to_go is not None and len(first) > config.beam:
        first = _nearest_the_goal(first, x, y, cost_to_go, occupancy, config.beam)
    return first


def _witness(history: list, motion: _Motion, spawn: tuple, arrival: float) -> Witness:
    """Walk back through the kept states from the arrival, then integrate the chosen
    primitives forward again (the same operations): the commands and poses of the witness."""
    prims = []
    index = 0
    for parent, prim in reversed(history):
        prims.append(int(prim[index]))
        index = int(parent[index])
    prims.reverse()
    state = [np.array([v]) for v in (*spawn, 0.0, 0.0)]
    poses, commands = [spawn], []
    zero = np.zeros(1, dtype=np.int64)
    for k, p in enumerate(prims):
        v, w, xs, ys, ths = motion.advance(*state, np.array([p]), zero)
        x, y, th = xs[-1], ys[-1], ths[-1]
        if k < len(prims) - 1:  # the search snapped the states it kept
            x, y, th = (snap_array(a, STATE_RESOLUTION) for a in (x, y, th))
        commands.append((float(v[0]), float(w[0])))
        poses.append((float(x[0]), float(y[0]), float(th[0])))
        state = [x, y, th, v, w]
    return Witness(motion.period, np.array(commands), np.array(poses), arrival)
