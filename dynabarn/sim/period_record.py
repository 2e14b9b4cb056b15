"""What the loop hands observers each control period (`PeriodRecord`); a Tick is made from
a period's numbers one way (`sim.tick.tick_from`).

A `Tick` carries fresh copies and derived numbers (the laser's pose, the clearance, the
distance to the goal); making one costs the episode's process about 30 us a period, most
of it where caches are cold. The loop makes it, and the poses since the last period, only
when an observer asks (`PeriodRecord.tick`, `.poses`, made once for all observers). An
observer that takes the period's own numbers instead (`on_tick_period`,
`on_poses_period`: the writer-process recorder) makes the Tick elsewhere with `tick_from`
and `TickFacts`, and takes the poses of many periods at once (`pose_span`,
`Episode.pose_steps`): the same functions on the same numbers, so the same bits.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from dynabarn.interfaces.events import Tick, listens
from dynabarn.metrics import Outcome


class PeriodSource(Protocol):
    """What a period's record reads of its episode (`sim.episode.Episode` is one): declared
    here, so the record does not import the episode that makes it."""

    step: int
    outcome: Outcome | None

    def tick_record(self, debug: dict, tracks=None) -> Tick: ...

    def poses_between(self, first: int) -> tuple[np.ndarray, np.ndarray]: ...

    def period_numbers(self) -> tuple: ...


class PeriodRecord:
    """One control period for observers: its Tick and poses made on first request."""

    __slots__ = ("_poses", "_tick", "debug", "episode", "first", "tracks")

    def __init__(self, episode: PeriodSource, debug: dict, tracks, first: int) -> None:
        self.episode, self.debug, self.tracks, self.first = episode, debug, tracks, first
        self._tick: Tick | None = None
        self._poses: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def tick(self) -> Tick:
        if self._tick is None:
            self._tick = self.episode.tick_record(self.debug, self.tracks)
        return self._tick

    @property
    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """(times, poses) at the pose rate since the last period (`Episode.poses_between`)."""
        if self._poses is None:
            self._poses = self.episode.poses_between(self.first)
        return self._poses

    def pose_span(self) -> tuple[int, int, bool]:
        """(first step, last step, ended): what `Episode.pose_steps` makes this period's
        pose steps of, later (the poses of steps already run never change)."""
        episode = self.episode
        return self.first, episode.step, episode.outcome is not None

    def numbers(self) -> tuple:
        """The period's own numbers for `tick_from`, as references (copy what you keep):
        (time, scan, pose, velocity, command, raw command (v, w), obstacles, planner ms,
        clearance: None unless the world's shapes need the simulation to compute it)."""
        return self.episode.period_numbers()


def observer_hooks(observers) -> tuple[list, list]:
    """The period hooks the loop calls: each observer's `on_tick_period` where it listens to
    ticks, its `on_poses_period` where it listens to poses (`events.listens`)."""
    heard = [(obs, *listens(obs)) for obs in observers]
    return [o.on_tick_period for o, ticks, _ in heard if ticks], [o.on_poses_period for o, _, poses in heard if poses]
