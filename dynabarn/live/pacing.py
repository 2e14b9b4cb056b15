"""Pacing an episode to the wall clock: `Pacer`, an `EpisodeObserver`.

An episode runs as fast as the machine allows; to be watched (a viewer, a live stream) it
runs at `rate` times real time instead: after each control tick the pacer sleeps until
the wall clock catches up with simulated time. A pause holds the episode between ticks.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from dynabarn.interfaces.events import EpisodeObserver


class Pacer(EpisodeObserver):
    """Holds each control tick until `start + sim_time / rate` on the wall clock.

    Args:
        rate: simulated seconds per wall-clock second (1: real time).
        while_waiting: called every few milliseconds while paused or ahead of time (a
            viewer keeps its window responsive with it); may raise to end the episode.
    """

    def __init__(self, rate: float = 1.0, *, while_waiting: Callable[[], None] | None = None) -> None:
        if not rate > 0:
            raise ValueError(f"rate must be positive, got {rate}")
        self.rate = rate
        self.while_waiting = while_waiting
        self.paused = threading.Event()
        self._t0 = 0.0
        self._offset = 0.0  # simulated time already shown when the clock was (re)started

    def toggle_pause(self) -> None:
        if self.paused.is_set():
            self.paused.clear()
        else:
            self.paused.set()

    def on_start(self, start) -> None:
        self._t0 = time.perf_counter()
        self._offset = 0.0

    def on_tick(self, tick) -> None:
        if self.paused.is_set():
            while self.paused.is_set():
                self._wait(0.02)
            # Resume from here: the pause does not count as time to catch up.
            self._t0, self._offset = time.perf_counter(), tick.time
        while (lag := self._t0 + (tick.time - self._offset) / self.rate - time.perf_counter()) > 0:
            self._wait(min(lag, 0.02))

    def _wait(self, seconds: float) -> None:
        if self.while_waiting is not None:
            self.while_waiting()
        time.sleep(seconds)

    def on_poses(self, times, poses) -> None: ...

    def on_end(self, result) -> None: ...
