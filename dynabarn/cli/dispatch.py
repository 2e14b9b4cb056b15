"""One entry point for every command: `python -m dynabarn COMMAND ...` (also
`python -m dynabarn.cli`), for environments where the installed scripts are not on PATH."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence

from dynabarn import cli
from dynabarn.cli.common import EXIT_USAGE
from dynabarn.errors import DynabarnError
from dynabarn.registry import Registry

COMMANDS: dict[str, Callable[[Sequence[str] | None], int]] = {
    name.removesuffix("_main"): getattr(cli, name) for name in cli.__all__
}
"""Command name (`run` for `dynabarn-run`) -> its main: this package's own."""
INSTALLED = Registry("command", COMMANDS, group="dynabarn.commands")
"""And the commands other packages add under the entry-point group `dynabarn.commands`
(name = "module:main", a main(argv) -> int), run as `python -m dynabarn NAME`."""


def _summary(command: Callable) -> str:
    """The first line of the command module's docstring, without its "`dynabarn-x`: " head."""
    doc = (sys.modules[command.__module__].__doc__ or "").strip()
    first = doc.splitlines()[0] if doc else ""
    return first.split(": ", 1)[-1]


def main(argv: Sequence[str] | None = None, prog: str = "python -m dynabarn") -> int:
    try:
        return _main(argv, prog)
    except BrokenPipeError:  # `python -m dynabarn --help | head`: the reader left, as for cat
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 0


def _main(argv: Sequence[str] | None, prog: str) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        print(f"usage: {prog} COMMAND [options]   (the same as dynabarn-COMMAND)\n\ncommands:")
        installed = INSTALLED.installed()
        for name in INSTALLED.names():
            summary = _summary(COMMANDS[name]) if name in COMMANDS else f"(from {installed[name].value})"
            print(f"  {name:<8} {summary}")
        print(f"\n{prog} COMMAND --help explains a command's options.")
        return 0 if args else EXIT_USAGE
    if args[0] in COMMANDS:  # this package's own: no scan of the installed packages
        return COMMANDS[args[0]](args[1:])
    names = INSTALLED.names()
    if args[0] not in names:
        print(f"{prog}: unknown command {args[0]!r}; choose from {', '.join(names)}", file=sys.stderr)
        return EXIT_USAGE
    try:
        command = INSTALLED.get_item(args[0])
    except DynabarnError as exc:  # an installed package that breaks on import
        print(f"{prog}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return command(args[1:])
