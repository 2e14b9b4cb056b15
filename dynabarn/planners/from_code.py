"""Planners named by their code on the command line, with nothing to package or register:

    dynabarn-run   --planner my_pkg.planners:Cautious --world 137
    dynabarn-bench --planner path/to/cautious.py:Cautious,dwa --out runs/mine

`MODULE:NAME` imports a module from the Python path; `FILE.py:NAME` loads a file. `NAME` is a
`Planner` subclass or a factory returning one: the same contract checks as a registered
planner (`check_planner_factory`). Results name it `my_pkg.planners:Cautious` or
`cautious.py:Cautious` (the file's name, not its folder: the same planner on any machine),
and each row records where it came from (`planner_code`: the module, or the file's name and
sha256). `--verify` runs such a row only when the person verifying names the same planner on
their own command line, and refuses a file whose bytes differ from the row's.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.interfaces.planner import check_planner_factory
from dynabarn.planners.registry import PLANNERS, register_planner
from dynabarn.planners.registry import planner_spec as registered_planner_spec

CODE_SPEC = re.compile(r"(?P<target>[^:@|]+):(?P<object>[A-Za-z_][A-Za-z0-9_]*)")
"""`TARGET:NAME`: a module's dotted name or a .py file's path, and a name in it."""


@dataclass(frozen=True)
class CodePlanner:
    """A planner loaded from code: its name in results and where it came from."""

    name: str
    object: str
    module: str = ""
    file: str = ""
    """The file's absolute path on this machine (never written to results: `identity`)."""
    sha256: str = ""
    search_path: str = ""
    """The folder a module was found in when it was not on the Python path (the current one):
    a worker process looks there too."""

    def identity(self) -> dict:
        """What a results row records of it: the module, or the file's name and sha256."""
        if self.file:
            return {"file": Path(self.file).name, "sha256": self.sha256, "object": self.object}
        return {"module": self.module, "object": self.object}

    @property
    def source(self) -> str:
        """The spec that loads it again (in a worker process)."""
        return f"{self.file or self.module}:{self.object}"


LOADED: dict[str, CodePlanner] = {}
"""Planners loaded from code in this process, by their name in results."""


def is_code_spec(spec: str) -> bool:
    """Whether a `--planner` entry names code (`TARGET:NAME`) rather than a registered planner."""
    return ":" in spec.partition("@")[0]


def _file_module(path: Path, digest: str):
    name = f"dynabarn_planner_file_{digest[:16]}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise DynabarnError(f"{path}: cannot be loaded as a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and pickling look the module up by name
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _import_module(target: str, search_path: str = "") -> tuple[object, str]:
    """Import `target` from the Python path; a module not there is looked for in the current
    folder (or `search_path`), added at the path's end, where it shadows nothing installed
    (the commands keep the current folder off the path: `processes`)."""
    import os

    if search_path and search_path not in sys.path:
        sys.path.append(search_path)
    try:
        return importlib.import_module(target), search_path
    except ModuleNotFoundError as exc:
        here = os.getcwd()
        if search_path or exc.name != target.split(".")[0] or here in sys.path:
            raise
        sys.path.append(here)
        return importlib.import_module(target), here


def load_code_planner(spec: str, search_path: str = "") -> CodePlanner:
    """Load `MODULE:NAME` or `FILE.py:NAME`, check it as a planner factory and register it
    in this process under its name in results; one `DynabarnError` line when it cannot be."""
    match = CODE_SPEC.fullmatch(spec.strip())
    if match is None:
        raise DynabarnError(f"--planner {spec!r}: name code as MODULE:CLASS or FILE.py:CLASS")
    target, name = match["target"].strip(), match["object"]
    is_file = target.endswith(".py") or "/" in target
    try:
        if is_file:
            path = Path(target).expanduser().resolve()
            if not path.is_file() or path.suffix != ".py":
                raise DynabarnError(f"--planner {spec!r}: {target} is not a .py file")
            digest = hashlib.sha256(path.read_bytes()).hexdigest()
            module = _file_module(path, digest)
            planner = CodePlanner(f"{path.name}:{name}", name, file=str(path), sha256=digest)
        else:
            module, found_in = _import_module(target, search_path)
            planner = CodePlanner(f"{target}:{name}", name, module=target, search_path=found_in)
    except DynabarnError:
        raise
    except (Exception, SystemExit) as exc:  # the user's code: its error in one line
        raise DynabarnError(f"--planner {spec!r}: loading {target} raised {type(exc).__name__}: {exc}") from None
    factory = getattr(module, name, None)
    if factory is None:
        raise DynabarnError(f"--planner {spec!r}: {target} has no {name}")
    try:
        check_planner_factory(factory)
    except (TypeError, ValueError) as exc:
        raise DynabarnError(f"--planner {spec!r}: {exc}") from None
    known = LOADED.get(planner.name)
    if known is not None and known != planner:
        raise DynabarnError(f"--planner {spec!r}: another planner is already named {planner.name} here")
    if planner.name not in PLANNERS:
        register_planner(factory, name=planner.name)
    LOADED[planner.name] = planner
    return planner


def load_again(code: CodePlanner) -> None:
    """In a worker process (a sweep's, `--verify`'s): load the planner the parent loaded,
    unless this process has it; refuse code that changed since (its sha256 differs)."""
    if code.name in LOADED:
        return
    if load_code_planner(code.source, code.search_path) != code:
        raise DynabarnError(f"{code.source} changed since it was named (its sha256 differs)")


def planner_spec(spec: str) -> tuple[str, dict, str]:
    """`registry.planner_spec` for what a command line names: `NAME`, `NAME@PRESET`, and
    planners from code (`MODULE:CLASS`, `FILE.py:CLASS`, with `@PRESET` too), loaded and
    registered in this process first."""
    name, sep, preset = spec.strip().partition("@")
    if is_code_spec(name):
        spec = load_code_planner(name.strip()).name + sep + preset
    return registered_planner_spec(spec)
