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

import contextlib
import time
from collections.abc import Sequence
from pathlib import Path

from dynabarn.errors import EndEpisode
from dynabarn.interfaces.events import EpisodeObserver, EpisodeStart, check_hooks
from dynabarn.interfaces.observation import Observation
from dynabarn.interfaces.planner import Planner, check_planner
from dynabarn.metrics import INTERRUPTED, PLANNER_RAISED, EpisodeResult, Outcome
from dynabarn.processes import no_interrupts
from dynabarn.protocol import EvalProtocol
from dynabarn.provenance import versions
from dynabarn.sim.episode import Episode
from dynabarn.sim.period_record import PeriodRecord, observer_hooks
from dynabarn.sim.result import episode_result
from dynabarn.sim.simulation import Simulation
from dynabarn.sim_config import SimConfig


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
    check_planner(planner)  # before anything runs: one line
    sim = world if isinstance(world, Simulation) else Simulation(world, config=config)
    episode = Episode(sim, protocol, seed=seed, privileged=planner.privileged)
    start = episode_start(
        episode,
        protocol,
        planner=planner_name or planner.name,
        planner_config=planner.config(),
        versions=versions() | planner.versions(),
    )
    loop = EpisodeLoop(episode, start, observers)
    try:
        planner.reset(episode.info)
        observation = loop.first()
        while episode.outcome is None:
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
                episode.end(Outcome.ERROR, f"{PLANNER_RAISED} {type(exc).__name__}: {exc}")
                break
            planning_ms = _planning_ms(planner, c0)
            tracks = episode.score_tracks(planner.tracks())
            if loop.period(raw_v, raw_w, planner_ms=planning_ms, debug=planner.debug, tracks=tracks) is Outcome.ERROR:
                break
            observation = loop.observation  # the period ended with it
    except KeyboardInterrupt:
        _end_interrupted(loop, planner)
        raise
    finish_planner(planner, episode.outcome.value if episode.outcome else "error")
    return loop.result()


def episode_start(
    episode: Episode, protocol: EvalProtocol, *, planner: str, planner_config: dict, versions: dict
) -> EpisodeStart:
    """What observers learn when `episode` starts, driven by `planner` (its name in results)."""
    sim = episode.sim
    return EpisodeStart(
        world=sim.world,
        world_path=sim.world_path,
        world_sha256=sim.world_sha256,
        protocol=protocol,
        planner=planner,
        planner_config=planner_config,
        seed=episode.seed,
        clock_offset=episode.clock_offset,
        config=sim.config,
        info=episode.info,
        versions=versions,
        world_xml=sim.world_xml,
    )


class EpisodeLoop:
    """The loop step every driver of an episode shares: one control period of a command,
    then the period handed to the observers. `run_episode` drives it with a planner's
    commands; the Gymnasium environments (`learn.env`, `learn.vector_env`) with the actions
    they are given, and so DAgger's and the demonstrations' collectors, which step them.

    Args:
        episode: the episode, started.
        start: what observers learn at its start (None: no observers, no result).
        observers: its observers (`on_start` is called here).
    """

    def __init__(
        self,
        episode: Episode,
        start: EpisodeStart | None,
        observers: Sequence[EpisodeObserver] = (),
        *,
        observes: bool = True,
    ) -> None:
        if observers and start is None:
            raise ValueError("observers need the episode's start")
        self.episode, self.start, self.observers = episode, start, tuple(observers)
        self.observes = observes
        """Whether a period ends with the next observation (False: a batch of worlds casts
        its scans together, `learn.vector_env`)."""
        self.observation: Observation | None = None
        """The last observation made: the first (`first`), then each period's last act."""
        for observer in self.observers:
            check_hooks(observer)
        for observer in self.observers:
            observer.on_start(start)
        self._tick_hooks, self._pose_hooks = observer_hooks(self.observers)

    def first(self) -> Observation:
        """The episode's first observation: what the first command answers."""
        self.observation = self.episode.observe()
        return self.observation

    def period(self, raw_v: float, raw_w: float, *, planner_ms: float = 0.0, debug=None, tracks=None) -> Outcome | None:
        """Drive (raw_v, raw_w) for one control period (`Episode.apply`: limited, stepped,
        judged), hand the period to the observers, with the planner's time, its `debug()`
        (called only when an observer listens) and its scored tracks, and, while the episode
        goes on, end with the next observation (`observation`); the outcome if it ended.
        Every driver steps an episode so: `run_episode` with a planner, the Gymnasium
        environments with their actions."""
        episode = self.episode
        episode.planner_ms[episode.n_ticks] = planner_ms
        first = episode.step
        if episode.apply(raw_v, raw_w) is Outcome.ERROR:
            return Outcome.ERROR
        if self.observers:
            # The Tick and the poses are made when an observer first asks for them.
            period = PeriodRecord(episode, debug() if debug is not None else {}, tracks, first)
            try:
                for on_tick in self._tick_hooks:
                    on_tick(period)
            except EndEpisode as exc:  # a person watching ended it (closed the viewer)
                if episode.outcome is None:
                    episode.end(Outcome.ERROR, str(exc) or "ended by an observer")
            for on_poses in self._pose_hooks:
                on_poses(period)
        if episode.outcome is None and self.observes:
            self.observation = episode.observe()
        return episode.outcome

    def result(self) -> EpisodeResult:
        """The ended episode's result, handed to the observers."""
        result = episode_result(self.episode, self.start)
        for observer in self.observers:
            observer.on_end(result)
        return result


def _end_interrupted(loop: EpisodeLoop, planner: Planner) -> None:
    """Ctrl-C or SIGTERM: the episode judged as interrupted and every observer ended (the
    recording closed whole), through a second, impatient Ctrl-C."""
    with no_interrupts():
        loop.episode.end(Outcome.ERROR, INTERRUPTED)
        loop.result()
        finish_planner(planner, INTERRUPTED)


def _planning_ms(planner: Planner, since: float) -> float:
    """Milliseconds since `since`, less what the planner waited on purpose (a ROS stack's
    start-up, pacing to the wall clock: `waited_ms`): planning time, not waiting time."""
    return (time.perf_counter() - since) * 1e3 - planner.waited_ms


def finish_planner(planner: Planner, outcome: str) -> None:
    """The planner's end-of-episode hook (the loop's, and the runner's where something
    outside the loop broke); a planner's `finish` is safe to call twice."""
    with contextlib.suppress(Exception):  # releasing resources must not turn a judged episode into a crash
        planner.finish(outcome)
