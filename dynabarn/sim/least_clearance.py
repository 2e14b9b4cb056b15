"""An episode's least clearance, evaluated only where it can be the least.

The metric is the footprint's clearance at every physics step (20,000 in a 100 s episode)
against where every obstacle was, then the least. Evaluated everywhere it cost 17 ms per
100 s episode, half of it re-evaluating the schedules: 6 % of the runner.

A clearance cannot fall faster than the footprint and the obstacles move: it is a least
distance between shapes, so moving any of them by at most d changes it by at most d. Between
two evaluated steps a and b with clearances c_a and c_b, and D the most the footprint (its
centre's path, plus its corners' turn) and any obstacle (`SchedulePlayer.max_speed`) can
have moved from a to b, no step has less than (c_a + c_b - D) / 2. So every SAMPLE_STRIDE-th
step is evaluated, and in full only the stretches whose bound is not above the least value
found. The result is the full evaluation's, bit for bit: the step where the least value is
attained is always evaluated, by the same function on the same numbers (each step's
clearance is computed alone; a test compares both ways on every kind of world).

Evaluated everywhere as before: obstacles with their own clocks (reactive ones: their
positions are logged, there is no schedule to bound), stretches where a looping schedule
jumps back to its start, and any episode with a non-finite value.
"""

from __future__ import annotations

import math

import numpy as np

from dynabarn.robot import JACKAL
from dynabarn.sim.simulation import Simulation
from dynabarn.worlds.schedule import SchedulePlayer

RESULT_CHUNK = 1000
"""Physics steps per batch of a full evaluation: the schedules' and the clearance's
temporaries stay in cache (a 100 s episode at once: 22 ms, in chunks: 17)."""
SAMPLE_STRIDE = 20
"""Physics steps between evaluated steps (one control period at the default rates)."""
MARGIN = 1e-6
"""[m] added to the bound's test: far above the rounding of the bound's sums (1e-13 m), so
rounding never leaves out a stretch that holds the least value."""
CORNER_REACH = math.hypot(JACKAL.length / 2, JACKAL.width / 2)
"""[m] the footprint's farthest point from its centre: how far a turn by 1 rad moves it at most."""


def least_clearance(sim: Simulation, player: SchedulePlayer, traj: np.ndarray, dt: float) -> float:
    """The least clearance over the poses traj (T, 3) of physics steps 0..T-1 against the
    obstacles of `player`'s schedules at those steps' times (and the static cylinders)."""
    n_steps = len(traj)
    samples = np.arange(0, n_steps, SAMPLE_STRIDE)
    if samples[-1] != n_steps - 1:
        samples = np.append(samples, n_steps - 1)
    at_samples = _clearance(sim, player, traj, samples, dt)
    best = float(at_samples.min())
    if not np.isfinite(at_samples).all() or len(samples) < 3:
        return full_clearance(sim, player, traj, dt)
    # The most any point of the footprint moved in each step: its centre's step, plus the
    # turn of its farthest corner (a chord is shorter than its arc).
    step = np.diff(traj, axis=0)
    turn = np.abs((step[:, 2] + math.pi) % (2 * math.pi) - math.pi)
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(step[:, 0], step[:, 1]) + CORNER_REACH * turn)])
    reach = travelled[samples[1:]] - travelled[samples[:-1]] + player.max_speed() * dt * np.diff(samples)
    bound = 0.5 * (at_samples[:-1] + at_samples[1:] - reach)
    jumped = player.clock_wraps(samples[:-1] * dt, samples[1:] * dt)
    # Not finite: an obstacle's speed unbounded (a segment without duration): all of them.
    open_ = np.flatnonzero(~(bound > best + MARGIN) | jumped)
    if len(open_) == 0:
        return best
    # The steps strictly inside each open stretch.
    lo, hi = samples[open_] + 1, samples[open_ + 1]
    counts = hi - lo
    inside = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(int(counts.sum()))
    for i in range(0, len(inside), RESULT_CHUNK):
        c = _clearance(sim, player, traj, inside[i : i + RESULT_CHUNK], dt)
        if c.size:
            best = min(best, float(c.min()))
    return best


def full_clearance(sim: Simulation, player: SchedulePlayer | None, traj: np.ndarray, dt: float, log=None) -> float:
    """The least clearance evaluated at every step, in chunks: against the schedules, or
    against the positions `log` (T, n, 2) the obstacles with their own clocks took."""
    best = math.inf
    for i in range(0, len(traj), RESULT_CHUNK):
        j = min(len(traj), i + RESULT_CHUNK)
        xy = log[i:j] if log is not None else player.positions_at(np.arange(i, j) * dt)[0]
        c = sim.clearance(traj[i:j], xy, static=True)
        if c.size:
            best = min(best, float(c.min()))
    return best


def _clearance(sim: Simulation, player: SchedulePlayer, traj: np.ndarray, steps: np.ndarray, dt: float) -> np.ndarray:
    """The clearance (len(steps),) at the given physics steps (their times alone: the bits
    of the same steps in a full evaluation)."""
    xy, _ = player.positions_at(steps * dt)
    return sim.clearance(traj[steps], xy, static=True)
