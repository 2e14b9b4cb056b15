"""An ended episode's `EpisodeResult`: outcome, time, score, SPL, clearance, smoothness."""

from __future__ import annotations

import time

import numpy as np

from dynabarn.interfaces.events import EpisodeStart
from dynabarn.metric_registry import computed
from dynabarn.metrics import METRICS, EpisodeFacts, EpisodeResult, Outcome, path_length
from dynabarn.protocol import EvalProtocol
from dynabarn.provenance import machine, portable_path
from dynabarn.sim.episode import Episode
from dynabarn.sim.least_clearance import full_clearance, least_clearance
from dynabarn.worlds.spec import WorldSpec


def _optimal_length(protocol: EvalProtocol, world: WorldSpec, goal: tuple[float, float]) -> float:
    """SPL's shortest path: the world's reference path when the protocol says so, else a straight line."""
    ref = world.provenance.get("reference_path_length") if protocol.reference_from_world else None
    if ref is not None:
        return max(float(ref) - protocol.goal_tolerance, 0.0)
    return protocol.optimal_path_length(goal)


def _min_clearance(episode: Episode, traj: np.ndarray, step: int) -> float:
    """The least clearance over every physics step 0..step, against where the obstacles
    were (scripted ones: their schedules; reactive ones: what they logged)."""
    sim, dt = episode.sim, episode.sim.config.dt
    if episode.reactive is None:
        return least_clearance(sim, episode.player, traj, dt)
    log = episode.reactive.log
    log[step] = log[max(step - 1, 0)] if step else log[0]
    return full_clearance(sim, None, traj, dt, log=log)


def episode_result(episode: Episode, start: EpisodeStart) -> EpisodeResult:
    """The metrics of an ended episode (docs/concepts/protocols.md)."""
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
    clearance = _min_clearance(episode, traj, step)
    wall = time.perf_counter() - episode.wall_t0
    goal = (float(sim.goal[0]), float(sim.goal[1]))
    reference = sim.world.provenance.get("reference_path_length") if protocol.reference_from_world else None
    facts = EpisodeFacts(
        success=success,
        time=ep_time,
        sim_time=sim_time,
        path_length=length,
        optimal_length=_optimal_length(protocol, sim.world, goal),
        score=protocol.score(success, ep_time, reference),
        min_clearance=clearance,
        tick_v=episode.tick_v[:n_ticks],
        tick_w=episode.tick_w[:n_ticks],
        tick_w_cmd=episode.tick_w_cmd[:n_ticks],
        control_period=cfg.control_period,
        planner_ms=episode.planner_ms[:n_ticks],
        wall_time=wall,
        clock_offset=start.clock_offset,
    )
    return EpisodeResult(
        world=sim.world.name,
        planner=start.planner,
        protocol=protocol.name,
        seed=start.seed,
        outcome=outcome,
        reason=reason,
        **{m.name: m.compute(facts) for m in METRICS},  # each metric as `metrics.METRICS` defines it
        n_ticks=n_ticks,
        world_file=portable_path(sim.world_path),
        world_sha256=sim.world_sha256,
        versions=start.versions,
        machine=machine(),
        planner_config=start.planner_config,
        protocol_version=protocol.version,
        tracking=episode.track_scorer.summary() if episode.track_scorer is not None else None,
        added_metrics=computed(facts),  # those registered or installed beyond the table
    )
