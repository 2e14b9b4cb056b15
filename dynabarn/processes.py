"""Child processes: they must not outlive the process that started them (a viewer's server,
a ROS master, a bridge node, pool workers): on Linux they get SIGTERM when their parent
dies, even by SIGKILL or `os._exit` (how pool workers end, without running atexit
handlers). And they never import from the current folder (`safe_path_for_children`)."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Callable, Iterator, Sequence

SAFE_PATH = {"PYTHONSAFEPATH": "1"}
"""Python's safe-path mode (3.11+) for every interpreter we start: `python -m ...` and
`python -c ...` (how multiprocessing's spawn starts a worker) then leave the current folder
off `sys.path`, so a `numpy.py`, `struct.py` or `dynabarn/` where a user runs a command is
never imported in a child."""


ONE_THREAD = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""What PyTorch's (and MKL's) intra-op thread pools read when they start: a sweep's workers
each get one thread, since the workers already fill the cores (a committed 2-job sweep ran
the same network at 18.8 ms a call where another took 0.6 ms; here, beside a busy core, one
thread per worker measured 1.95 against 2.08 ms)."""


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform says, as a
    container or `taskset` limits it; else the machine's): what worker counts default to."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # macOS has no affinity
        return os.cpu_count() or 1


def one_thread_per_worker() -> None:
    """The workers this process starts from now on use one intra-op thread each, unless the
    person asked for more (either variable already set): in this process's environment,
    which spawned and forked workers read when they first import PyTorch."""
    if not any(name in os.environ for name in ONE_THREAD):
        os.environ.update(dict.fromkeys(ONE_THREAD, "1"))


def safe_path_for_children() -> None:
    """Every child this process starts from now on runs in safe-path mode (`SAFE_PATH`):
    set in this process's environment, which `subprocess`, multiprocessing's spawn and a
    local Ray cluster's raylet pass on. Called by everything that starts interpreters."""
    os.environ.update(SAFE_PATH)


def leave_the_current_folder_off_the_path() -> None:
    """`python -m dynabarn` as `python -P -m dynabarn`: Python puts the folder it was
    started in first on `sys.path` for `-m`, where a planted module or a `*.dist-info` with
    an entry point (a planner, a command) would be found before anything installed. Drop
    that entry (the package itself is already imported: a `dynabarn/` there is the one thing
    only `-P` on the command line can keep out) and start every child in safe-path mode."""
    if not sys.flags.safe_path and sys.path:
        first = sys.path[0]
        try:
            here = os.path.realpath(first or os.curdir) == os.path.realpath(os.getcwd())
        except OSError:
            here = True
        if here:
            del sys.path[0]
    safe_path_for_children()


@contextlib.contextmanager
def in_empty_folder() -> Iterator[str]:
    """Run the block from a new empty folder, then come back: for libraries that put the
    current folder on their workers' `sys.path` themselves (Ray adds the driver's), so that
    what they add holds nothing to import."""
    here = os.getcwd()
    empty = tempfile.mkdtemp(prefix="dynabarn-empty-")
    os.chdir(empty)
    try:
        yield here
    finally:
        os.chdir(here)


def _die_with_parent() -> None:  # pragma: no cover - runs in the child before exec
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def worker_start(parent: int) -> None:
    """Initializer of pool workers (the sweep's, DAgger's collectors): SIGTERM ends them
    outright (not the command's "end like Ctrl-C" handler inherited through fork), and they
    end with their parent even when it is killed with SIGKILL, releasing the results folder's
    lock and the caller's pipes."""
    import signal

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    torch = sys.modules.get("torch")  # forked after the parent imported it: its pool is sized already
    if torch is not None and os.environ.get("OMP_NUM_THREADS") == "1":
        torch.set_num_threads(1)
    if sys.platform.startswith("linux"):
        _die_with_parent()
        if os.getppid() != parent:  # the sweep died before the signal was asked for
            os._exit(1)


def map_in_workers(function: Callable, items: Sequence, jobs: int) -> Iterator:
    """`function` over `items`: here, in order, with one job (or one item); else in a pool
    of min(jobs, items) spawned workers, as they finish. The workers run in safe-path mode,
    with one thread each, and die with this process (`worker_start`)."""
    if jobs <= 1 or len(items) <= 1:
        yield from map(function, items)
        return
    import multiprocessing as mp

    safe_path_for_children()
    one_thread_per_worker()
    with mp.get_context("spawn").Pool(min(jobs, len(items)), initializer=worker_start, initargs=(os.getpid(),)) as pool:
        yield from pool.imap_unordered(function, items)


def die_with_parent() -> Callable[[], None] | None:
    """A `preexec_fn` for `subprocess.Popen` (None where the platform has no such signal)."""
    return _die_with_parent if sys.platform.startswith("linux") else None


def ignore_interrupts() -> dict:
    """Ctrl-C and SIGTERM ignored from now on (in the main thread; elsewhere signals do not
    arrive and nothing changes); the handlers they had, to put back."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    return {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}


@contextlib.contextmanager
def no_interrupts() -> Iterator[None]:
    """The block runs to its end through a further Ctrl-C or SIGTERM (`ignore_interrupts`,
    then the handlers put back): what an interrupted episode still writes (its recording's
    end) is not cut by a second, impatient Ctrl-C."""
    import signal

    previous = ignore_interrupts()
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
