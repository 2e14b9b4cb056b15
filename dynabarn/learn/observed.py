"""Observers of a Gymnasium environment's episodes (`DynaBARN-v0`'s `observers=`): the
same `EpisodeObserver`s a command's episode has, so a Gym episode is recorded to MCAP
(`McapRecorder`) or watched live as any other.

The environment makes them per episode (a factory given the episode's `info`: world,
trial seed), starts them with the episode (`EpisodeStart`, as `run_episode` does, the
driver named `gymnasium`), hands them every control period through the one loop step
(`sim.EpisodeLoop.period`), and ends them with the result, or, at a reset or close before
the episode ended, with an `error` result saying so (the recording is closed whole).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from dynabarn.interfaces import EpisodeObserver
from dynabarn.metrics import Outcome
from dynabarn.protocol import EvalProtocol
from dynabarn.provenance import versions
from dynabarn.sim import Episode, EpisodeLoop
from dynabarn.sim.loop import episode_start

DRIVER = "gymnasium"
"""Who drives a Gym episode, as its start names the planner: the agent stepping it."""
LEFT = "the environment was reset or closed before the episode ended"

ObserverFactory = Callable[[dict], Sequence[EpisodeObserver]]


class ObservedEpisodes:
    """Each episode's observers, from `factory(info)`; none without a factory."""

    def __init__(self, factory: ObserverFactory | None) -> None:
        if factory is not None and not callable(factory):
            raise ValueError(f"observers must be a function of the episode's info returning observers, got {factory!r}")
        self.factory = factory
        self._open: EpisodeLoop | None = None

    def loop(self, episode: Episode, protocol: EvalProtocol, info: dict, *, observes: bool = True) -> EpisodeLoop:
        """The episode's loop step, with its observers started (ending the last episode's
        first, if it has not ended); `observes`: as `EpisodeLoop`'s."""
        self.leave()
        observers = list(self.factory(dict(info))) if self.factory is not None else []
        if not observers:
            return EpisodeLoop(episode, None, observes=observes)
        start = episode_start(episode, protocol, planner=DRIVER, planner_config={}, versions=versions())
        self._open = EpisodeLoop(episode, start, observers, observes=observes)
        return self._open

    def ended(self) -> None:
        """The episode ended: its observers get its result."""
        loop, self._open = self._open, None
        if loop is not None:
            loop.result()

    def leave(self) -> None:
        """A reset or close before the episode ended: it ends as `error`, saying why."""
        if self._open is not None and self._open.episode.outcome is None:
            self._open.episode.end(Outcome.ERROR, LEFT)
        self.ended()
