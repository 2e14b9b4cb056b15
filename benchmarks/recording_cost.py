"""Where recording's time goes in one long episode (`make bench`, issue 32's item 4).

The runner with `stop` on the hard world (100 s, 1,000 control periods) four ways: no
observer; an observer that does nothing (what the loop pays to build each period's `Tick`
and poses for observers); the MCAP recorder in the episode's process (`McapRecorder`, each
hook timed: the work the writer process now does); and the default, `BackgroundRecorder`
(what its hooks cost the episode's process, and the wait in `on_end` for the writer to
finish the file). Milliseconds per episode, the best of `repeat` runs each.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from dynabarn.errors import EndEpisode
from dynabarn.interfaces import EpisodeObserver, Planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder
from dynabarn.recording.background import BackgroundRecorder
from dynabarn.runner import EpisodeSpec, run_spec
from dynabarn.sim import Simulation
from dynabarn.worldset import resolve_world

HOOKS = ("on_start", "on_tick", "on_tick_period", "on_poses", "on_poses_period", "on_end")
PER_PERIOD = ("on_tick", "on_tick_period", "on_poses", "on_poses_period")


def _timed(base: type) -> type:
    """`base` with the wall time of each of its hooks summed in `spent` (only the hooks it
    overrides: the loop chooses by which ones an observer overrides)."""
    hooks = [h for h in HOOKS if getattr(base, h) is not getattr(EpisodeObserver, h)]

    def __init__(self, path: Path) -> None:
        base.__init__(self, path)
        self.spent = dict.fromkeys(hooks, 0.0)

    def wrap(hook: str):
        def timed(self, *args) -> None:
            t0 = time.perf_counter()
            getattr(base, hook)(self, *args)
            self.spent[hook] += time.perf_counter() - t0

        return timed

    return type(f"Timed{base.__name__}", (base,), {"__init__": __init__, **{h: wrap(h) for h in hooks}})


def _episode(world_id: int, observer: EpisodeObserver | None) -> float:
    sim = Simulation(resolve_world(world_id))
    spec = EpisodeSpec.make(sim.world_path, "stop", get_protocol("barn"), seed=0)
    t0 = time.perf_counter()
    run_spec(spec, sim=sim, observers=[observer] if observer else [])
    return time.perf_counter() - t0


def _best_recorded(world_id: int, recorder: type, repeat: int, tmp: Path) -> tuple[float, dict[str, float]]:
    best: tuple[float, dict[str, float]] | None = None
    for i in range(repeat):
        rec = recorder(tmp / f"{recorder.__name__}{i}.mcap")
        total = _episode(world_id, rec)
        if best is None or total < best[0]:
            best = (total, dict(rec.spent))
    return best


def recording_breakdown(world_id: int, repeat: int = 3) -> dict[str, float]:
    """Milliseconds of one `stop` episode: the runner alone, the loop's per-period records for
    observers, each hook of the recorder in this process and what it costs beside its hooks,
    and the default writer-process recorder's hooks, its wait at the end and its total."""
    alone = min(_episode(world_id, None) for _ in range(repeat))
    null = min(_episode(world_id, EpisodeObserver()) for _ in range(repeat))
    with tempfile.TemporaryDirectory() as tmp:
        total, spent = _best_recorded(world_id, _timed(McapRecorder), repeat, Path(tmp))
        _episode(world_id, BackgroundRecorder(Path(tmp) / "warm.mcap"))  # the writer process started once
        bg_total, bg_spent = _best_recorded(world_id, _timed(BackgroundRecorder), repeat, Path(tmp))
    ms = {"runner alone": alone, "records for observers": null - alone}
    ms |= {f"McapRecorder {hook}": t for hook, t in spent.items()}
    ms["McapRecorder, beside its hooks"] = total - null - sum(spent.values())
    ms["total, recorder in this process"] = total
    ms["BackgroundRecorder per-period hooks (episode's process)"] = sum(bg_spent.get(h, 0.0) for h in PER_PERIOD)
    ms["BackgroundRecorder on_start + on_end (the wait for the file)"] = bg_spent["on_start"] + bg_spent["on_end"]
    ms["total, writer process (the default)"] = bg_total
    return {k: 1000.0 * v for k, v in ms.items()}


class _EndsAtOnce(Planner):
    """A planner that ends its episode at the first tick: what remains is the fixed cost."""

    name = "ends_at_once"

    def act(self, obs):
        raise EndEpisode("done")


def fixed_costs(world_id: int, repeat: int = 20) -> dict[str, float]:
    """Milliseconds an episode's recording costs whatever its length (one that ends at its
    first tick): none, the writer process (the default; started once before), in this process."""
    sim = Simulation(resolve_world(world_id))
    spec = EpisodeSpec.make(sim.world_path, _EndsAtOnce.name, get_protocol("barn"), seed=0)

    def once(make) -> float:
        best = float("inf")
        with tempfile.TemporaryDirectory() as tmp:
            for i in range(repeat):
                t0 = time.perf_counter()
                observers = [make(Path(tmp) / f"{i}.mcap")] if make else []
                run_spec(spec, planner=_EndsAtOnce(), sim=sim, observers=observers)
                best = min(best, time.perf_counter() - t0)
        return 1000.0 * best

    none = once(None)
    once(BackgroundRecorder)  # the writer process started before the clock runs
    return {
        "an episode's fixed cost, not recorded": none,
        "  recording it, writer process (the default)": once(BackgroundRecorder),
        "  recording it in this process": once(McapRecorder),
    }
