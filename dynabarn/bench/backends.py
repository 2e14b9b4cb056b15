"""Where jobs run: `local` (a process pool on this machine) or `ray` (Ray tasks on a
cluster or a local Ray; `pip install dynabarn[ray]`). Both run the same `run_job`, so
the same job gives the same row on either."""

from __future__ import annotations

import functools
import os
import sys
from collections.abc import Iterator

from dynabarn.bench.jobs import Job, row_head, run_job
from dynabarn.errors import DynabarnError
from dynabarn.processes import in_empty_folder, one_thread_per_worker, safe_path_for_children, worker_start

MAX_ATTEMPTS = 3
"""Times an episode is started when its worker process dies under it (killed, out of
memory, a crash in native code); then it is recorded as an infrastructure failure."""


def _local_backend(jobs: list[Job], n_workers: int) -> Iterator[dict]:
    if n_workers <= 1 or len(jobs) <= 1:
        for job in jobs:
            yield run_job(job)
        return
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    # fork is fast and carries run-time registrations, but not safe once PyTorch has run in
    # this process: its OpenMP pool does not survive fork, and the workers hang on their
    # first parallel operation (seen: a sweep of bc,td3 stuck with every worker waiting on
    # a futex). Then fresh interpreters (spawn) run the episodes.
    forkable = sys.platform.startswith("linux") and "torch" not in sys.modules
    ctx = mp.get_context("fork" if forkable else "spawn")
    safe_path_for_children()  # a spawned worker starts as `python -c`: never from the current folder
    one_thread_per_worker()  # the workers fill the cores: PyTorch's threads would fight over them
    attempts: dict[str, int] = {}
    remaining = list(jobs)
    while remaining:
        # A dead worker breaks the whole pool (concurrent.futures notices, unlike
        # multiprocessing.Pool, which waits forever) and every unfinished episode in it. They
        # run again in a new pool; one caught in two breaks runs alone, so the episode that
        # kills its worker is found without blaming the others.
        suspect = next((j for j in remaining if attempts.get(j.key, 0) >= MAX_ATTEMPTS - 1), None)
        batch = [suspect] if suspect is not None else remaining
        remaining = [j for j in remaining if j is not suspect] if suspect is not None else []
        pool = ProcessPoolExecutor(
            min(n_workers, len(batch)), mp_context=ctx, initializer=worker_start, initargs=(os.getpid(),)
        )
        pending = {pool.submit(run_job, job): job for job in batch}
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    job = pending.pop(future)
                    try:
                        yield future.result()
                    except BrokenProcessPool:
                        attempts[job.key] = attempts.get(job.key, 0) + 1
                        if attempts[job.key] < MAX_ATTEMPTS:
                            remaining.append(job)
                        else:
                            yield _dead_worker_row(job)
        except BaseException:
            for process in list(getattr(pool, "_processes", {}).values()):
                process.kill()
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


def _dead_worker_row(job: Job, reason: str = "") -> dict:
    return {
        **row_head(job),
        "outcome": "error",
        "reason": reason or f"infrastructure: the worker process died {MAX_ATTEMPTS} times running this episode",
        "retry": True,
    }


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
    # Ray's own convention: RAY_ADDRESS names the cluster when --address does not (ray.init
    # reads it too; checked here, so an address nothing answers at is one line within seconds).
    address = address or os.environ.get("RAY_ADDRESS", "").strip() or None
    if started_here and address:
        _check_ray_address(address)
    local = started_here and not address
    if local:
        _start_local_ray(ray, n_workers)
    elif started_here:
        ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    # A local cluster's workers start in an empty folder (see _start_local_ray): each episode
    # runs from the sweep's folder, where its relative paths lead.
    remote = ray.remote(num_cpus=1)(_run_job_in if local else run_job)
    run = functools.partial(remote.remote, os.getcwd()) if local else remote.remote
    jobs_of = {run(job): job for job in jobs}
    pending = list(jobs_of)
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            try:
                yield ray.get(done[0])
            except ray.exceptions.RayError as exc:  # a lost node or worker: the machine's failure
                first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                yield _dead_worker_row(jobs_of[done[0]], f"infrastructure: Ray: {type(exc).__name__}: {first}")
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()


LOOPBACK_RAY = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0"}
"""Ray's single-machine mode: the node's address is 127.0.0.1 and every server of a local
cluster (GCS, raylet, object manager, workers, this process's own) listens there only (by
default they listen on every interface: `ss -ltn` showed `*:PORT` for each)."""


def _start_local_ray(ray, n_workers: int) -> None:
    """A Ray cluster on this machine for one sweep: on loopback only (`LOOPBACK_RAY`, in the
    environment its processes inherit and in the constant Ray read at import), its workers in
    safe-path mode and dying with their raylet, and started from an empty folder, since Ray
    puts the driver's current folder first on every worker's `sys.path` itself."""
    from ray._private import ray_constants

    os.environ.update(LOOPBACK_RAY)
    safe_path_for_children()
    one_thread_per_worker()
    ray_constants.ENABLE_RAY_CLUSTER = False  # read when the node's address is chosen
    with in_empty_folder():
        ray.init(num_cpus=n_workers, include_dashboard=False, ignore_reinit_error=True, log_to_driver=False)


def _run_job_in(folder: str, job: Job) -> dict:
    """`run_job` from `folder` (a local Ray worker starts in an empty one)."""
    os.chdir(folder)
    return run_job(job)


def _check_ray_address(address: str, timeout: float = 5.0) -> None:
    """Fail within seconds on an address nothing answers at (Ray itself retries for minutes)."""
    import socket

    if address == "auto":
        return
    text = address.split("://", 1)[-1]
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or not 1 <= int(port) <= 65535 or not host:
        raise DynabarnError(f"--address {address!r}: give HOST:PORT (e.g. 10.0.0.1:6379), ray://HOST:PORT or auto")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            pass
    except OSError as exc:
        raise DynabarnError(
            f"no Ray cluster answers at {address} ({exc.strerror or exc}); start one with `ray start --head`"
        ) from None
