"""The benchmark harness: planners x worlds x trials, in parallel, resumable, never
losing a result; its summary with the paper's Fig. 5 beside ours; and the golden set.

jobs (one episode each) -> backends (local pool, Ray) -> results (results.jsonl,
metadata.json) -> sweep (run what is not done yet) -> summary (tables, Fig. 5);
golden (the committed episodes every machine must reproduce).
"""

from dynabarn.bench.jobs import Job, make_jobs, run_job
from dynabarn.bench.results import (
    METADATA,
    RESULTS,
    append_row,
    certified_episodes,
    check_or_write_metadata,
    jsonable_args,
    locked,
    metadata,
    paper_worlds,
    read_results,
    write_worlds,
)
from dynabarn.bench.summary import (
    DIFFICULTIES,
    PAPER_FIG5,
    format_table,
    plot_fig5,
    summarise,
    wilson_interval,
    write_summary,
)
from dynabarn.bench.sweep import SweepReport, run_sweep

__all__ = [
    "DIFFICULTIES",
    "METADATA",
    "PAPER_FIG5",
    "RESULTS",
    "Job",
    "SweepReport",
    "append_row",
    "certified_episodes",
    "check_or_write_metadata",
    "format_table",
    "jsonable_args",
    "locked",
    "make_jobs",
    "metadata",
    "paper_worlds",
    "plot_fig5",
    "read_results",
    "run_job",
    "run_sweep",
    "summarise",
    "wilson_interval",
    "write_summary",
    "write_worlds",
]
