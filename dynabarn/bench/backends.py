"""Where jobs run: `local` (a process pool on this machine) or `ray` (Ray tasks on a
cluster or a local Ray; `pip install dynabarn[ray]`). Both run the same `run_job`, so
the same job gives the same row on either."""

from __future__ import annotations

import sys
from collections.abc import Iterator

from dynabarn.bench.jobs import Job, run_job
from dynabarn.errors import DynabarnError


def _local_backend(jobs: list[Job], n_workers: int) -> Iterator[dict]:
    if n_workers <= 1:
        for job in jobs:
            yield run_job(job)
        return
    import multiprocessing as mp

    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    with ctx.Pool(n_workers) as pool:
        try:
            yield from pool.imap_unordered(run_job, jobs, chunksize=1)
        except KeyboardInterrupt:
            pool.terminate()
            raise


def run_jobs(jobs: list[Job], *, backend: str = "local", n_workers: int = 1, address: str | None = None):
    """Rows of the jobs as they finish (in any order), on the chosen backend."""
    if backend == "ray":
        return _ray_backend(jobs, n_workers, address)
    return _local_backend(jobs, n_workers)


def _ray_backend(jobs: list[Job], n_workers: int, address: str | None) -> Iterator[dict]:
    try:
        import ray
    except ImportError:
        raise DynabarnError("the ray backend needs Ray: pip install 'dynabarn[ray]'") from None
    started_here = not ray.is_initialized()
    if started_here:
        kwargs = {"address": address} if address else {"num_cpus": n_workers, "include_dashboard": False}
        ray.init(ignore_reinit_error=True, log_to_driver=False, **kwargs)
    remote = ray.remote(num_cpus=1)(run_job)
    pending = [remote.remote(job) for job in jobs]
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield ray.get(done[0])
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()
