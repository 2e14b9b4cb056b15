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
from dynabarn.bench.results import (
    RESULTS,
    append_row,
    certified_episodes,
    check_or_write_metadata,
    locked,
    metadata,
    paper_worlds,
    prepare_resume,
    read_results,
    write_worlds,
)
from dynabarn.errors import DynabarnError
from dynabarn.metrics import Outcome


@dataclass
class SweepReport:
    ran: int = 0
    skipped: int = 0
    errors: int = 0
    wall_time: float = 0.0
    rows: list[dict] = field(default_factory=list)
    summary: list[dict] = field(default_factory=list)
    """The folder's whole summary (every planner run into it), when the folder was written."""
    paths: dict[str, Path] = field(default_factory=dict)
    """What was written beside the rows: summary (csv, md, png) and report (html)."""


def run_sweep(
    jobs: list[Job],
    out_dir: Path,
    *,
    backend: str = "local",
    n_workers: int = 1,
    address: str | None = None,
    progress: Callable[[Iterable, int], Iterable] | None = None,
    folder: bool = True,
    arguments: dict | None = None,
    argv: list[str] | None = None,
    force: bool = False,
    title: str = "",
) -> SweepReport:
    """Run the jobs not already in OUT/results.jsonl, appending each result as it arrives.

    With `folder` (the default), the folder `dynabarn-bench` writes, from Python too:
    `metadata.json` (its sweep, and this invocation: `arguments` and `argv`, by default that
    it came from Python) and `worlds.json` before, the summary and `report.html` after
    (`force`: start the folder over). Without it, only the rows (demonstrations, speed
    benchmarks).

    Holds the folder's lock throughout; jobs are de-duplicated by key; rows of
    infrastructure failures from an earlier run are run again. A results file that cannot
    be written (disk full) stops the sweep with one line; every row written stays."""
    out_dir = Path(out_dir)
    jobs = list({j.key: j for j in jobs}.values())  # the same episode once
    results_path = out_dir / RESULTS
    with locked(out_dir):
        if folder:
            try:
                meta = metadata(arguments or {"from": "dynabarn.bench.run_sweep"}, jobs, argv=argv or [])
                check_or_write_metadata(out_dir, meta, force=force)
                write_worlds(out_dir, jobs)
            except OSError as exc:
                raise DynabarnError(f"cannot write to {out_dir}: {exc.strerror}") from None
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
        every_row = read_results(results_path)
        report.rows = [r for r in every_row if r["key"] in wanted]
        if folder and every_row:
            report.summary, report.paths = write_folder_summary(out_dir, every_row, title)
    return report


def write_folder_summary(out_dir: Path, rows: list[dict], title: str = "") -> tuple[list[dict], dict[str, Path]]:
    """The folder's whole sweep (every planner run into it, same worlds and protocol), so a
    planner added later is summarised beside the others and the floor: `summary.csv`,
    `summary.md`, `fig5.png` and `report.html`."""
    from dynabarn.bench.report import write_report
    from dynabarn.bench.summary import summarise, write_summary

    summary = summarise(rows, paper_worlds(out_dir), certified_episodes(out_dir))
    paths = write_summary(summary, out_dir, title=title)
    paths["html"] = write_report(out_dir, rows, summary=summary)
    return summary, paths
