"""Per-call time of the search planners and how a pool of workers scales them.

    python benchmarks/planner_scaling.py [--jobs 1,4,8,16]

Prints each planner's mean and 95th-percentile time per `act` over six worlds of every
difficulty (as `make bench`'s planner rows), then the wall time and x real time of
`predictive` on the 48 hard worlds 200-247 (seed 0) run by a pool of 1, 4, 8 and 16
workers (docs/speed.md's 16-core table), and with `--sweep`, each named planner's 60
episodes of `paper60` (seed 0: `sweep_speed.py`'s sweep, without the sweep's results
file, so that it runs where the recording extras are not installed) by each pool. Each
worker runs one episode at a time in its own process, with one intra-op thread
(OMP_NUM_THREADS=1 unless set)."""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time

import numpy as np

from dynabarn.interfaces import EpisodeObserver
from dynabarn.planners import planner_spec
from dynabarn.protocol import get_protocol
from dynabarn.runner import EpisodeSpec, run_spec
from dynabarn.worldset import PAPER60, resolve_world

WORLDS = (0, 15, 105, 155, 205, 215)
HARD = range(200, 248)


def planner_compute(planner: str, worlds=WORLDS, **extra) -> tuple[float, float, int]:
    """(mean, p95 [ms], calls) of `planner.act` over one episode in each of `worlds` (the
    planner's configuration with `extra` on top, e.g. a student's `policy`)."""
    times: list[float] = []

    class Timer(EpisodeObserver):
        def on_tick(self, tick):
            times.append(tick.planner_ms)

    name, config, _ = planner_spec(planner)
    for w in worlds:
        spec = EpisodeSpec.make(resolve_world(w), name, get_protocol("barn"), config={**config, **extra}, seed=0)
        run_spec(spec, observers=[Timer()])
    arr = np.array(times)
    return float(arr.mean()), float(np.percentile(arr, 95)), len(arr)


def _episode(item: tuple[str, int]) -> tuple[float, float]:
    planner, world = item
    name, config, _ = planner_spec(planner)
    result = run_spec(EpisodeSpec.make(resolve_world(world), name, get_protocol("barn"), config=config, seed=0)).result
    return result.sim_time, result.wall_time


def pool_speed(planner: str, worlds, jobs: int) -> tuple[float, float]:
    """(wall seconds, x real time) of one episode per world run by a pool of `jobs` workers."""
    t0 = time.perf_counter()
    with mp.get_context("spawn").Pool(jobs) as pool:
        rows = pool.map(_episode, [(planner, w) for w in worlds], chunksize=1)
    wall = time.perf_counter() - t0
    return wall, sum(r[0] for r in rows) / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--jobs", default="1,4,8,16", help="pool sizes to time (default: 1,4,8,16)")
    parser.add_argument("--planners", default="oracle,oracle_present,predictive,dwa", help="planners to time per call")
    parser.add_argument("--sweep", default="", help="planners whose paper60 sweep each pool runs (default: none)")
    args = parser.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    for planner in filter(None, args.planners.split(",")):
        mean, p95, calls = planner_compute(planner)
        print(f"{planner}: {mean:.2f} ms per call (p95 {p95:.2f}), {calls} calls", flush=True)
    for jobs in (int(j) for j in args.jobs.split(",")):
        wall, rtf = pool_speed("predictive", HARD, jobs)
        print(f"predictive, {len(HARD)} hard episodes, {jobs} workers: {wall:.1f} s, {rtf:.0f}x real time", flush=True)
        for planner in filter(None, args.sweep.split(",")):
            wall, rtf = pool_speed(planner, PAPER60, jobs)
            print(f"  {planner}, paper60 ({len(PAPER60)} episodes), {jobs} workers: {wall:.1f} s, {rtf:.0f}x real time")


if __name__ == "__main__":
    main()
