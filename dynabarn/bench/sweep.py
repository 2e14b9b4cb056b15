"""Benchmark harness: planners x worlds x trials, in parallel, resumable, never losing a result.

A sweep is a list of `Job`s (planner, its configuration, world file, protocol, seed). Each
finished episode is appended to `OUT/results.jsonl` as one flushed and fsync'ed line
(full metrics, versions, world hash), so Ctrl-C or a crash loses nothing finished, and
running the same command again skips what is done. An episode whose code raises is
recorded as outcome `error` with its traceback and the sweep goes on.

Backends: `local` (a process pool on this machine) and `ray` (Ray tasks on a cluster or a
local Ray; `pip install dynabarn[ray]`). Both run the same `run_job`, so the same job gives
the same row on either.

The summary per planner and difficulty: success rate with a 95% Wilson interval,
collision and timeout rates, mean time of successes, BARN score, SPL and minimum
clearance; printed, and written as `summary.csv`, `summary.md` and a Fig. 5-style
`fig5.png` with the paper's published values beside ours.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from dynabarn.bench.backends import run_jobs
from dynabarn.bench.jobs import Job
from dynabarn.bench.results import RESULTS, append_row, locked, prepare_resume, read_results
from dynabarn.errors import DynabarnError
from dynabarn.metrics import Outcome


@dataclass
class SweepReport:
    ran: int = 0
    skipped: int = 0
    errors: int = 0
    wall_time: float = 0.0
    rows: list[dict] = field(default_factory=list)


def run_sweep(
    jobs: list[Job],
    out_dir: Path,
    *,
    backend: str = "local",
    n_workers: int = 1,
    address: str | None = None,
    progress: Callable[[Iterable, int], Iterable] | None = None,
) -> SweepReport:
    """Run the jobs not already in OUT/results.jsonl, appending each result as it arrives.

    Holds the folder's lock throughout; jobs are de-duplicated by key; rows of
    infrastructure failures from an earlier run are run again. A results file that cannot
    be written (disk full) stops the sweep with one line; every row written stays."""
    out_dir = Path(out_dir)
    jobs = list({j.key: j for j in jobs}.values())  # the same episode once
    results_path = out_dir / RESULTS
    with locked(out_dir):
        try:
            done = {r["key"] for r in prepare_resume(results_path)}
        except OSError as exc:
            raise DynabarnError(f"cannot prepare {results_path} for resuming: {exc.strerror}") from None
        todo = [j for j in jobs if j.key not in done]
        report = SweepReport(skipped=len(jobs) - len(todo))
        t0 = time.perf_counter()
        try:
            if any(j.record != "none" for j in todo):
                Path(todo[0].recordings_dir).mkdir(parents=True, exist_ok=True)
            stream = run_jobs(todo, backend=backend, n_workers=n_workers, address=address)
            if progress is not None:
                stream = progress(stream, len(todo))
            with results_path.open("a") as f:
                for row in stream:
                    append_row(f, row)
                    report.ran += 1
                    report.errors += row.get("outcome") == Outcome.ERROR.value
        except OSError as exc:
            raise DynabarnError(
                f"cannot write to {out_dir}: {exc.strerror}; the {report.ran} episodes finished in this run are kept "
                f"in {results_path}; free the space (or fix the folder) and run the same command again to go on"
            ) from None
        report.wall_time = time.perf_counter() - t0
        wanted = {j.key for j in jobs}
        report.rows = [r for r in read_results(results_path) if r["key"] in wanted]
    return report
