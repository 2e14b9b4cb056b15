"""Where a planner's time per call goes: each part its `act` calls, timed by cProfile.

    python benchmarks/planner_breakdown.py [PLANNER ...]

For each planner, one episode in each of three worlds (easy, medium, hard; seed 0) runs
under cProfile, and the time of every call that `act` makes directly (the rollout, the
clearances, the tracker, the costmap, the global plan, the network, numpy's own reductions)
is summed over the episodes and divided by the number of calls to `act`. The profiler adds
its own cost to every Python call, so the parts add up to more than the unprofiled time
per call (`make bench`'s planner rows); they show the shares, not the absolute figure.
`make bench` prints the same table for the search planners."""

from __future__ import annotations

import cProfile
import pstats
import sys

from dynabarn.planners import planner_spec
from dynabarn.protocol import get_protocol
from dynabarn.runner import EpisodeSpec, run_spec
from dynabarn.worldset import resolve_world

WORLDS = (15, 155, 215)
PLANNERS = ("oracle", "predictive", "dwa", "dwa@dwa_dynabarn_authors", "trajectory_planner", "teb")


def _label(func: tuple[str, int, str]) -> str:
    """A profiled function as `module.function` (within the package) or its own name."""
    path, _, name = func
    if "/dynabarn/" in path:
        module = path.split("/dynabarn/", 1)[1].removesuffix(".py").replace("/", ".")
        return f"{module}.{name}"
    return name.strip("<>").replace("built-in method ", "").replace("method ", "")


def breakdown(planner: str, worlds: tuple[int, ...] = WORLDS) -> tuple[int, list[tuple[str, float]]]:
    """(calls to `act`, [(part, ms per call)], largest first, `act`'s own lines last)."""
    name, config, _ = planner_spec(planner)
    profile = cProfile.Profile()
    for world in worlds:
        spec = EpisodeSpec.make(resolve_world(world), name, get_protocol("barn"), config=config, seed=0)
        profile.runcall(run_spec, spec)
    stats = pstats.Stats(profile).stats
    acts = [f for f in stats if f[2] == "act" and "/dynabarn/planners/" in f[0]]
    calls = sum(stats[f][1] for f in acts if not any(c in acts for c in stats[f][4]))  # the outermost act
    parts: dict[str, float] = {}
    own = 0.0
    for act in acts:
        own += stats[act][2]
    for func, (_, _, _, _, callers) in stats.items():
        for caller, edge in callers.items():
            if caller in acts and func not in acts:
                parts[_label(func)] = parts.get(_label(func), 0.0) + edge[3]
    rows = sorted(((k, 1e3 * v / max(calls, 1)) for k, v in parts.items()), key=lambda kv: -kv[1])
    return calls, [*rows, ("(act's own lines)", 1e3 * own / max(calls, 1))]


def print_breakdown(planners=PLANNERS, *, top: int = 8) -> None:
    for planner in planners:
        calls, rows = breakdown(planner)
        total = sum(ms for _, ms in rows)
        print(f"where {planner}'s time per call goes (profiled, {calls} calls) [ms]{total:>12.2f}")
        shown = rows[:top] + ([rows[-1]] if rows[-1] not in rows[:top] else [])
        rest = total - sum(ms for _, ms in shown)
        for label, ms in shown:
            print(f"  {label:<64}{ms:>12.2f}{ms / total:>9.0%}")
        if rest > 0.005:
            print(f"  {'(the rest)':<64}{rest:>12.2f}{rest / total:>9.0%}")


if __name__ == "__main__":
    print_breakdown(sys.argv[1:] or PLANNERS)
