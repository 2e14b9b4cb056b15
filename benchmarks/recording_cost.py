"""Where recording's time goes in one long episode (`make bench`, issue 32's item 4).

The runner with `stop` on the hard world (100 s, 1,000 control periods) three ways: no
observer, an observer that does nothing (what the loop pays to build each period's `Tick`
and poses for observers), and the MCAP recorder with each of its hooks timed. Milliseconds
per episode, the best of `repeat` runs each.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from dynabarn.interfaces import EpisodeObserver
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder
from dynabarn.sim import Simulation, run_episode
from dynabarn.worldset import resolve_world

HOOKS = ("on_start", "on_tick", "on_poses", "on_end")


class _TimedRecorder(McapRecorder):
    """The recorder, with the wall time of each hook summed."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.spent = dict.fromkeys(HOOKS, 0.0)

    def _timed(self, hook: str, *args) -> None:
        t0 = time.perf_counter()
        getattr(McapRecorder, hook)(self, *args)
        self.spent[hook] += time.perf_counter() - t0

    def on_start(self, start) -> None:
        self._timed("on_start", start)

    def on_tick(self, tick) -> None:
        self._timed("on_tick", tick)

    def on_poses(self, times, poses) -> None:
        self._timed("on_poses", times, poses)

    def on_end(self, result) -> None:
        self._timed("on_end", result)


def _episode(world_id: int, observer: EpisodeObserver | None) -> float:
    sim = Simulation(resolve_world(world_id))
    t0 = time.perf_counter()
    run_episode(sim, get_planner("stop"), get_protocol("barn"), seed=0, observers=[observer] if observer else [])
    return time.perf_counter() - t0


def recording_breakdown(world_id: int, repeat: int = 3) -> dict[str, float]:
    """Milliseconds of one `stop` episode: the runner alone, the loop's per-period records for
    observers, each recorder hook, and what the recorder costs beside its hooks."""
    alone = min(_episode(world_id, None) for _ in range(repeat))
    null = min(_episode(world_id, EpisodeObserver()) for _ in range(repeat))
    best: tuple[float, dict[str, float]] | None = None
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeat):
            recorder = _TimedRecorder(Path(tmp) / f"{i}.mcap")
            total = _episode(world_id, recorder)
            if best is None or total < best[0]:
                best = (total, dict(recorder.spent))
    total, spent = best
    ms = {"runner alone": alone, "records for observers": null - alone}
    ms |= {f"recorder {hook}": spent[hook] for hook in HOOKS}
    ms["recorder, beside its hooks"] = total - null - sum(spent.values())
    ms["total with recording"] = total
    return {k: 1000.0 * v for k, v in ms.items()}
