"""One error hierarchy: every failure a person can cause derives from `DynabarnError`.

The command-line entry points catch `DynabarnError`, print its message on one line and
exit non-zero; a traceback appears only under `--debug`.
"""

from __future__ import annotations


class DynabarnError(Exception):
    """Base class of every error meant for the person at the keyboard."""


class ProfileError(DynabarnError, ValueError):
    """A motion profile or profile set whose parameters cannot be sampled."""


class WorldError(DynabarnError):
    """A world that is missing, malformed or not a DynaBARN world."""


class ImportFormatError(DynabarnError):
    """A file handed to `dynabarn-worlds import` that does not match its format."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread of a command so that it ends as Ctrl-C does (an
    episode judged as interrupted, its recording closed and kept), then exits 143."""


class EndEpisode(Exception):
    """Raised by a planner to end its episode on purpose (outcome `error`, this reason)."""


def unknown_choice(kind: str, name: str, available: list[str] | tuple[str, ...]) -> str:
    """The message for a name not in a registry: the nearest names first ("did you mean"),
    then everything available."""
    import difflib

    near = difflib.get_close_matches(str(name), [str(a) for a in available], n=2, cutoff=0.75)
    hint = f"; did you mean {' or '.join(repr(n) for n in near)}?" if near else ""
    return f"unknown {kind} {name!r}{hint}; available: {', '.join(sorted(available))}"


LEARN_INSTALL = "pip install 'dynabarn[learn]'"
LEARN_EXTRA = "the learn extra: pip install 'dynabarn[learn]' (in a checkout: pip install -e '.[learn]')"
"""What to install for PyTorch and Gymnasium, said the same way everywhere."""


class NotInstalledHere(DynabarnError):
    """Something this install lacks to run what was asked (an extra, a ROS stack, a built
    workspace): `--verify` reports such a row as not checked, with `install`, the command
    that adds it, never as a difference."""

    def __init__(self, message: str, install: str = "") -> None:
        super().__init__(message)
        self.install = install
