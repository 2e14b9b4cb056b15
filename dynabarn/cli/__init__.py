"""Command-line entry points, one module per command (common: what they share).

Each `*_main(argv)` returns an exit code; `[project.scripts]` names them. They load on first
use, so an installed script imports only its own command; and while it starts, Ctrl-C ends
it quietly (exit 130) instead of a traceback from whichever import it interrupted (the
`command` wrapper then takes over).
"""

import importlib
import os
import signal
import sys

_MAINS = {
    "bench_main": "bench",
    "demos_main": "demos",
    "export_main": "export",
    "render_main": "render",
    "replay_main": "replay",
    "ros_main": "ros",
    "run_main": "run",
    "teleop_main": "teleop",
    "train_main": "train",
    "worlds_main": "worlds",
}
__all__ = sorted(_MAINS)


def __getattr__(name: str):
    if name in _MAINS:
        return getattr(importlib.import_module(f"dynabarn.cli.{_MAINS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def interrupted_while_starting(signum, frame) -> None:  # pragma: no cover - a real Ctrl-C
    os.write(2, b"interrupted\n")
    os._exit(130)


# Only in this package's installed scripts (`dynabarn-run`, ...), never in a process that
# imports the package: `command` puts Python's own handler back when the body starts.
_SCRIPT = os.path.basename(sys.argv[0] if sys.argv else "").startswith("dynabarn-")
if _SCRIPT and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    signal.signal(signal.SIGINT, interrupted_while_starting)
