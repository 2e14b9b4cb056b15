"""Child processes that must not outlive the process that started them (a viewer's server,
a ROS master, a bridge node): on Linux they get SIGTERM when their parent dies, even by
SIGKILL or `os._exit` (how pool workers end, without running atexit handlers)."""

from __future__ import annotations

import sys
from collections.abc import Callable


def _die_with_parent() -> None:  # pragma: no cover - runs in the child before exec
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def worker_start(parent: int) -> None:
    """Initializer of the sweep's pool workers: SIGTERM ends them outright (not the
    command's "end like Ctrl-C" handler inherited through fork), and they end with the
    sweep even when it is killed with SIGKILL, releasing the results folder's lock and the
    caller's pipes."""
    import os
    import signal

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        _die_with_parent()
        if os.getppid() != parent:  # the sweep died before the signal was asked for
            os._exit(1)


def die_with_parent() -> Callable[[], None] | None:
    """A `preexec_fn` for `subprocess.Popen` (None where the platform has no such signal)."""
    return _die_with_parent if sys.platform.startswith("linux") else None
