"""How fast a sweep runs with each shipped planner: a fixed 60-episode sweep, 2 workers.

    python benchmarks/sweep_speed.py [--jobs N] [PLANNER ...]

The sweep is `paper60`'s 60 worlds, one trial each (seed 0), protocol `barn`, no recording:
what `dynabarn-bench --planner P --set paper60 --trials 1 --no-floor` runs. For each planner
it prints the sweep's wall time, the simulated seconds of its episodes, their ratio (x real
time, all workers together), and the planner's mean time per call across the episodes. The
ROS stacks are left out (their time is the stack's own). `make bench` prints the same
table; issue 42's aim is 30x real time or more on 2 cores for every planner."""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from dynabarn import bench, worldset
from dynabarn.planners import planner_spec
from dynabarn.protocol import get_protocol

SHIPPED = (
    "straight",
    "dwa",
    "dwa@dwa_dynamic",
    "dwa@dwa_dynabarn_authors",
    "trajectory_planner",
    "teb",
    "teb@teb_dynamic",
    "predictive",
    "oracle_present",
    "oracle",
    "bc",
    "td3",
    "dagger",
)
"""Every planner the package ships and the presets the results use (not `stop`, which
ends no episode before the time limit, nor `ros`)."""
AIM = 30.0
"""x real time a 2-job sweep should reach (issue 42)."""


@dataclass(frozen=True)
class SweepSpeed:
    planner: str
    episodes: int
    wall_s: float
    sim_s: float
    planner_ms: float
    """Mean per-call time over the episodes (each episode's mean weighted by its calls)."""

    @property
    def real_time_factor(self) -> float:
        return self.sim_s / self.wall_s


def sweep_speed(planner: str, *, jobs: int = 2, worlds: str = "paper60", ids: list[int] | None = None) -> SweepSpeed:
    """Run the fixed sweep (or the worlds `ids` of it) for one planner in a temporary folder
    and time it."""
    name, config, label = planner_spec(planner)
    world_list = worldset.world_set(worlds, ids)
    episodes = bench.make_jobs([(name, config, label)], world_list, get_protocol("barn"), 1)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        bench.run_sweep(episodes, Path(tmp), n_workers=jobs, folder=False)
        wall = time.perf_counter() - t0
        rows = [json.loads(line) for line in (Path(tmp) / bench.RESULTS).read_text().splitlines()]
    sim = sum(r["sim_time"] for r in rows)
    calls = sum(r["n_ticks"] for r in rows)
    ms = sum(r["planner_ms_mean"] * r["n_ticks"] for r in rows) / max(calls, 1)
    return SweepSpeed(planner, len(rows), wall, sim, ms)


def print_sweep_speeds(planners=SHIPPED, *, jobs: int = 2) -> list[SweepSpeed]:
    print(f"a 60-episode sweep per planner (paper60, 1 trial, {jobs} jobs): x real time, aim >= {AIM:.0f}")
    print(f"{'planner':<30}{'wall [s]':>10}{'sim [s]':>10}{'x real time':>13}{'ms per call':>13}")
    speeds = []
    for planner in planners:
        s = sweep_speed(planner, jobs=jobs)
        speeds.append(s)
        mark = "" if s.real_time_factor >= AIM else "  (under the aim)"
        print(f"{planner:<30}{s.wall_s:>10.1f}{s.sim_s:>10.0f}{s.real_time_factor:>13.0f}{s.planner_ms:>13.2f}{mark}")
    return speeds


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("planners", nargs="*", default=list(SHIPPED), help="planners (default: every shipped one)")
    parser.add_argument("--jobs", type=int, default=2, help="workers (default: 2)")
    args = parser.parse_args(argv)
    print_sweep_speeds(args.planners, jobs=args.jobs)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
