"""What every command shares: its parser, the flags several commands take, error handling.

Errors a person can cause (`DynabarnError`) print one line on stderr and exit 2; a
traceback appears only with `--debug` (accepted before or after a subcommand). Ctrl-C
exits 130. A new command is one module in this package with a `main(argv) -> int`, plus
its line under `[project.scripts]` (docs/architecture.md, "Extending").
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import sys
from collections.abc import Callable, Sequence
from importlib.metadata import PackageNotFoundError, version

from dynabarn.cli import interrupted_while_starting
from dynabarn.errors import DynabarnError, ImportFormatError, Terminated
from dynabarn.limits import MAX_JOBS, MAX_SEED
from dynabarn.processes import ignore_interrupts

SET_HELP = (
    "world set: paper60, dynabarn300, a tier beyond the paper's hard (tier-dense, tier-fast, tier-mixed, "
    "tier-combined; generated on first use), or a folder with index.json"
)
"""--set's help, one text for every command that takes a world set."""
WORLD_HELP = (
    "a world by id or name (137, world_137, world_137.xml; from $DYNABARN_WORLDS, else the shipped 300) "
    "or the path of a world .xml"
)
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143  # 128 + SIGTERM, what a shell reports for a process that SIGTERM ended


def package_version() -> str:
    try:
        return version("dynabarn")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "0+unknown"


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows each option's default once: not again where the help already names it."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text.lower() or "(none:" in text.lower() or action.required:
            return text
        if action.default is None or action.default is False or action.default is argparse.SUPPRESS:
            return text
        return super()._get_help_string(action)


def prefer_offscreen_gl() -> None:
    """The command-line tools' choice of MuJoCo's OpenGL platform (read when mujoco is first
    imported): EGL (Mesa, no GPU needed) without a display; with one (or Xvfb), MuJoCo's
    default GLFW. An explicit MUJOCO_GL wins. Library users choose their own."""
    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"
    problem = gl_environment_problem(os.environ)
    if problem:  # mujoco's import would raise it as a traceback, in every command
        print(f"error: {problem}", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


_MUJOCO_GL = {
    "Linux": ("glfw", "glx", "egl", "osmesa"),
    "Darwin": ("glfw", "cgl"),
    "Windows": ("glfw", "wgl"),
}
"""MUJOCO_GL's platforms per system (mujoco's own list, less its spellings of on and off)."""
_GL_OFF_OR_ON = ("", "disable", "disabled", "off", "false", "0", "enable", "enabled", "on", "true", "1")


def gl_environment_problem(environ) -> str | None:
    """Why MUJOCO_GL and PYOPENGL_PLATFORM (the two environment variables that choose how
    MuJoCo renders) cannot work together, or None: mujoco checks them at import, with a
    traceback."""
    import platform

    gl = environ.get("MUJOCO_GL", "").lower().strip()
    valid = _MUJOCO_GL.get(platform.system(), ("glfw",))
    if gl not in valid and gl not in _GL_OFF_OR_ON:
        return f"MUJOCO_GL={environ['MUJOCO_GL']!r} is not one of {', '.join(valid)} (or unset)"
    pyopengl = environ.get("PYOPENGL_PLATFORM", "")
    if gl in ("egl", "osmesa") and pyopengl and pyopengl.lower() != gl:
        return f"PYOPENGL_PLATFORM={pyopengl!r} contradicts MUJOCO_GL={gl}: unset it or set it to {gl}"
    return None


class Parser(argparse.ArgumentParser):
    """argparse with one line per usage error (`prog: error: ...`, then exit 2); `--help`
    still shows the whole usage."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        parsed, rest = super().parse_known_args(args, namespace)
        # A required option with an old spelling (`add_renamed`) is checked here: either
        # spelling gives it, which argparse's own `required` cannot see.
        for dest, new in getattr(self, "renamed_required", ()):
            if getattr(parsed, dest, None) is None:
                self.error(f"the following arguments are required: {new}")
        return parsed, rest


def ranged(kind: type, low: float, high: float) -> Callable[[str], float]:
    """An argparse type: a number of `kind` (int or float) in [low, high]; NaN, infinities
    and runaway values are refused before anything runs."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not {'a whole number' if kind is int else 'a number'}"
            ) from None
        if not low <= value <= high:  # also False for NaN
            raise argparse.ArgumentTypeError(
                f"{text} is not in [{low:{'g' if kind is float else 'd'}}, {high:{'g' if kind is float else 'd'}}]"
            )
        return value

    parse.__name__ = kind.__name__  # argparse names the type in its messages
    return parse


def plain_name(text: str) -> str:
    """An argparse type: a name that becomes part of a file name (`files.PLAIN_NAME`)."""
    from dynabarn.files import plain_name_problem

    problem = plain_name_problem(text)
    if problem:
        raise argparse.ArgumentTypeError(f"{text!r} {problem}")
    return text


plain_name.__name__ = "name"


def make_parser(prog: str, description: str) -> argparse.ArgumentParser:
    prefer_offscreen_gl()  # every command builds its parser first, before mujoco is imported
    p = Parser(prog=prog, description=description, formatter_class=HelpFormatter)
    p.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    p.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    return p


class _Subcommands:
    """`add_subparsers` whose subcommands describe themselves and take `--debug` too."""

    def __init__(self, parser: argparse.ArgumentParser) -> None:
        self._sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add_parser(self, name: str, *, help: str, **kwargs) -> argparse.ArgumentParser:
        kwargs.pop("formatter_class", None)
        p = self._sub.add_parser(
            name,
            help=help,
            description=kwargs.pop("description", help[:1].upper() + help[1:] + "."),
            formatter_class=HelpFormatter,
            **kwargs,
        )
        # SUPPRESS: given only before the subcommand, the top-level value stays.
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show full tracebacks on errors")
        return p


def subcommands(parser: argparse.ArgumentParser) -> _Subcommands:
    return _Subcommands(parser)


SET_OF_WORLD_HELP = (
    "the world set --world is in: paper60, dynabarn300, a tier (tier-dense, tier-fast, tier-mixed, "
    "tier-combined; generated on first use) or a folder with index.json (default: $DYNABARN_WORLDS, else the "
    "shipped 300)"
)


def add_world(p: argparse.ArgumentParser) -> None:
    """`--set NAME --world ID`: the same two options wherever one world is named."""
    p.add_argument("--world", required=True, help=WORLD_HELP)
    p.add_argument("--set", default=None, help=SET_OF_WORLD_HELP)


class Renamed(argparse.Action):
    """An option's old spelling, kept for one release: it stores into the new option's place
    and says once, on stderr, what it is called now (`add_renamed`)."""

    def __init__(self, option_strings, dest, new: str = "", **kwargs) -> None:
        self.new = new
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        print(f"note: {option_string} is now {self.new}; the old spelling goes in the next release", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_renamed(p: argparse.ArgumentParser, old: str, new: str, dest: str, **kwargs) -> None:
    """Accept `old` for the option now called `new` (hidden from --help and the docs; it
    sets no default of its own). A required `new` stays required: either spelling gives it
    (`Parser.parse_known_args` checks)."""
    p.add_argument(old, dest=dest, action=Renamed, new=new, help=argparse.SUPPRESS, default=argparse.SUPPRESS, **kwargs)
    for action in p._actions:
        if new in action.option_strings and action.required:
            action.required = False
            p.renamed_required = [*getattr(p, "renamed_required", ()), (dest, new)]


def add_protocol(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--protocol", default="barn", help="evaluation protocol: barn, paper2022, barn-static or a .json file"
    )


def add_sim_settings(p: argparse.ArgumentParser) -> None:
    """The simulation's settings an episode carries, as declared on `SimConfig` (`sim_options`)."""
    from dynabarn.sim_config import sim_options

    for f in sim_options():
        low, high = f.metadata["range"]
        p.add_argument(
            f"--{f.name.replace('_', '-')}",
            type=ranged(float, low, high),
            default=f.default,
            help=f"{f.metadata['meaning']} [{f.metadata['unit']}] (default: {f.default:g})",
        )


def sim_settings(args: argparse.Namespace):
    """The `SimConfig` the options of `add_sim_settings` give."""
    from dynabarn.sim_config import SimConfig, sim_options

    return SimConfig(**{f.name: getattr(args, f.name) for f in sim_options()})


def add_trial_seed(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--seed", type=ranged(int, 0, MAX_SEED), default=0, help="trial seed: obstacle clock offset and laser noise"
    )


def result_keys(extra: tuple[str, ...] = (), *, tracked: bool = False) -> list[str]:
    """The keys of `--json`'s result, read off `EpisodeResult` (so `--help` and the
    documentation list exactly what is printed); `tracked`: also those of a planner that
    tracks obstacles (`tracking`)."""
    from dataclasses import fields

    from dynabarn.metrics import OPTIONAL_FIELDS, EpisodeResult

    chosen = {"tracking"} if tracked else set()
    names = [f.name for f in fields(EpisodeResult) if f.name not in OPTIONAL_FIELDS or f.name in chosen]
    return [*names, "recording", *extra]


def add_recording(p: argparse.ArgumentParser, planner: str = "<planner>", extra_keys: tuple[str, ...] = ()) -> None:
    """--log / --no-log / --runs-dir / --json: where one episode is recorded and how it is printed."""
    from pathlib import Path

    log = p.add_mutually_exclusive_group()
    log.add_argument(
        "--log",
        type=Path,
        default=None,
        help=f"MCAP file to record to (default: runs/<world>_{planner}_<protocol>_s<seed>.mcap)",
    )
    log.add_argument("--no-log", action="store_true", help="do not record")
    p.add_argument("--runs-dir", type=Path, default=Path("runs"), help="folder of default recordings")
    p.add_argument(
        "--json",
        action="store_true",
        help="print the full result as JSON instead of one line; its keys: "
        + ", ".join(result_keys(extra_keys))
        + "; and, for planners that track obstacles, tracking; with metrics added beyond the table "
        + "(registered or installed), added_metrics",
    )


def add_jobs(p: argparse.ArgumentParser) -> None:
    from dynabarn.processes import usable_cores

    p.add_argument(
        "--jobs",
        type=ranged(int, 1, MAX_JOBS),
        default=min(usable_cores(), MAX_JOBS),
        help=f"parallel workers (default: the cores this process may use; at most {MAX_JOBS})",
    )


EXIT_EPISODE_ERROR = 1


def planner_config(text: str | None) -> dict:
    """--planner-config: a preset name, a JSON file, or inline `key=value,key=value` (values as JSON)."""

    from dynabarn.planners import planner_presets, read_planner_config

    if not text:
        return {}
    if text in planner_presets() or text.endswith(".json"):
        return read_planner_config(text)
    cfg = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise DynabarnError(
                f"bad --planner-config item {item!r}: use key=value[,key=value], a .json file or a preset ("
                + ", ".join(planner_presets())
                + ")"
            )
        if key.strip() in cfg:  # the second value would silently win
            raise DynabarnError(f"bad --planner-config: {key.strip()!r} given twice")
        try:
            cfg[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            cfg[key.strip()] = value
        except (ValueError, RecursionError):  # a number of thousands of digits, nesting too deep
            raise DynabarnError(f"bad --planner-config value for {key.strip()!r}: not a number or JSON") from None
    return cfg


def one_line(text: str) -> str:
    """An error message on one line, whatever it quotes (a path with a newline in it, a
    library's multi-line message): line breaks shown as \\n."""
    return text.strip().replace("\r", "\\r").replace("\n", "\\n")


def command(main: Callable[[Sequence[str] | None], int]) -> Callable[[Sequence[str] | None], int]:
    """A command's `*_main`: Ctrl-C or SIGTERM outside its body too (while it starts, parses
    its options, or a second Ctrl-C while it ends) is one line and exit 130 or 143, never a
    traceback."""

    @functools.wraps(main)
    def wrapped(argv: Sequence[str] | None = None) -> int:
        import signal

        if signal.getsignal(signal.SIGINT) is interrupted_while_starting:  # started: Ctrl-C as usual
            signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            code = main(argv)
        except KeyboardInterrupt as exc:
            terminated = isinstance(exc, Terminated)
            print("terminated" if terminated else "interrupted", file=sys.stderr)
            code = EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
        if argv is None and code in (EXIT_INTERRUPTED, EXIT_TERMINATED):
            # A script, ending: a further Ctrl-C must not interrupt what it still closes.
            ignore_interrupts()
        return code

    return wrapped


def _terminate(signum, frame) -> None:
    raise Terminated()


def run_command(body: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """Run a command's body: one line and exit 2 for what a person caused, Ctrl-C (130) and
    SIGTERM (143) end it the same way, with one line saying what was kept."""
    import signal
    import threading

    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    try:
        return body(args)
    except DynabarnError as exc:
        if args.debug:
            raise
        # An import's problems are listed one per line, all at once; any other error is one line.
        print(f"error: {str(exc) if isinstance(exc, ImportFormatError) else one_line(str(exc))}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (Terminated)
        terminated = isinstance(exc, Terminated)
        kept = f"; {exc.args[0]}" if exc.args else ""
        print(f"{'terminated' if terminated else 'interrupted'}{kept}", file=sys.stderr)
        return EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
    except BrokenPipeError:  # `dynabarn-worlds show 137 | head`: the reader left, as for cat
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 0
    except OSError as exc:  # the machine said no: a full disk, a read-only folder, a path under a file
        if args.debug:
            raise
        where = f" ({exc.filename})" if exc.filename else ""
        print(f"error: {one_line(f'{exc.strerror or exc}{where}')}", file=sys.stderr)
        return EXIT_USAGE
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def progress_bar(desc: str, total: int | None = None, unit: str = "world"):
    from tqdm import tqdm

    return lambda it: tqdm(it, desc=desc, total=total, unit=unit, disable=None, leave=False)
