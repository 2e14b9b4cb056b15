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

import json
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from dynabarn.bench.backends import run_jobs
from dynabarn.bench.jobs import Job
from dynabarn.bench.results import RESULTS, append_row, read_results
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
    """Run the jobs not already in OUT/results.jsonl, appending each result as it arrives."""
    out_dir.mkdir(parents=True, exist_ok=True)
    results_path = out_dir / RESULTS
    # Drop a torn last line (a crash mid-write) so appends start on a fresh line.
    done_rows = read_results(results_path)
    if results_path.is_file():
        with results_path.open("w") as f:
            for row in done_rows:
                f.write(json.dumps(row, sort_keys=True) + "\n")
    done = {r["key"] for r in done_rows}
    todo = [j for j in jobs if j.key not in done]
    report = SweepReport(skipped=len(jobs) - len(todo))
    if any(j.record != "none" for j in todo):
        Path(todo[0].recordings_dir).mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    stream = run_jobs(todo, backend=backend, n_workers=n_workers, address=address)
    if progress is not None:
        stream = progress(stream, len(todo))
    with results_path.open("a") as f:
        for row in stream:
            append_row(f, row)
            report.ran += 1
            report.errors += row.get("outcome") == Outcome.ERROR.value
    report.wall_time = time.perf_counter() - t0
    wanted = {j.key for j in jobs}
    report.rows = [r for r in read_results(results_path) if r["key"] in wanted]
    return report
