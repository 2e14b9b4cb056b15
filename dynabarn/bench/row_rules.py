"""What a results row may name, checked as data before `--verify` runs anything: its key's
parts as names and values (never a path), the planners and protocols installed here, no
option that names a program, a file or an address unless the person verifying gives it,
and world files only inside the places worlds are (`world_roots`), hashed in pieces."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.files import plain_name_problem
from dynabarn.limits import MAX_SEED

MAX_KEY_CHARS = 65_536
"""A key is a planner's name and configuration, a file name and a few numbers: a few
hundred characters; a longer one is not one of ours."""


def parse_key(key: object) -> dict:
    """A row's key (`runner.EpisodeSpec.key`) as its parts: planner, config, world file
    name, protocol, seed and simulation settings, each checked as a name or a value (never a
    path): one `DynabarnError` line otherwise."""
    shown = repr(key)[:80]
    try:
        if not isinstance(key, str) or len(key) > MAX_KEY_CHARS:
            raise ValueError(f"not a string of at most {MAX_KEY_CHARS:,} characters")
        planner, rest = key.split("|", 1)
        config, end = json.JSONDecoder().raw_decode(rest)
        parts = rest[end:].split("|")
        if parts[0] != "" or len(parts) not in (4, 5):
            raise ValueError("fields after the configuration")
        sim = {}
        if len(parts) == 5:
            if not parts[4].startswith("sim="):
                raise ValueError("the simulation settings")
            sim = json.loads(parts[4][4:])
        if not isinstance(config, dict) or not isinstance(sim, dict):
            raise ValueError("the configuration")
        seed = int(parts[3]) if parts[3].isascii() and parts[3].isdigit() and len(parts[3]) <= 10 else -1
        if not 0 <= seed <= MAX_SEED:
            raise ValueError(f"seed {parts[3][:20]!r}: a whole number in [0, {MAX_SEED}]")
        names = [("planner", n) for n in planner.partition("@")[0].split(":", 1)]  # MODULE:CLASS, FILE.py:CLASS
        for what, name in (*names, ("protocol", parts[2]), ("world file", parts[1])):
            problem = plain_name_problem(name)
            if problem:
                raise ValueError(f"{what} {name[:40]!r} {problem}")
        if not parts[1].endswith(".xml"):
            raise ValueError(f"world file {parts[1][:40]!r}: a world file's name ends in .xml")
        return {
            "planner": planner,
            "config": config,
            "world": parts[1],
            "protocol": parts[2],
            "seed": seed,
            "sim": sim_settings(sim),
        }
    except (ValueError, IndexError, RecursionError) as exc:
        raise DynabarnError(f"results row key {shown} is not one dynabarn-bench writes ({exc})") from None


def sim_settings(sim: dict) -> dict:
    """A key's simulation settings, checked as `SimConfig` checks them (ValueError)."""
    from dataclasses import fields

    from dynabarn.sim_config import SimConfig

    known = {f.name for f in fields(SimConfig)}
    for name, value in sim.items():
        if name not in known:
            raise ValueError(f"unknown simulation setting {name[:40]!r} (known: {', '.join(sorted(known))})")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"simulation setting {name}={value!r:.40}: expected a number")
    try:
        SimConfig(**sim)
    except DynabarnError as exc:
        raise ValueError(str(exc)) from None
    return sim


@dataclass
class RowRules:
    """What this install lets a row name, looked up once per file (a registry scans the
    installed packages on each call: 7,320 rows took two minutes): its planners and
    protocols, each planner's external options, the folder's own protocol and what the
    person verifying gave."""

    planners: set[str]
    protocols: list[str]
    protocol: dict | None
    given: dict
    external: dict[str, dict[str, str]] = field(default_factory=dict)

    @classmethod
    def here(cls, protocol: dict | None, given: dict, code: set[str] = frozenset()) -> RowRules:
        """The rules of this install; of the planners from code (`from_code`), only those the
        person verifying named (`code`), whatever else this process has loaded."""
        from dynabarn.planners import available_planners
        from dynabarn.planners.from_code import LOADED
        from dynabarn.protocol import PROTOCOLS

        planners = {p for p in available_planners() if p not in LOADED or p in code}
        return cls(planners, PROTOCOLS.names(), protocol, dict(given))

    def external_options(self, planner: str) -> dict[str, str]:
        from dynabarn.planners.registry import external_options

        if planner not in self.external:
            self.external[planner] = external_options(planner)
        return self.external[planner]


def row_inputs(file: Path, number: int, row: dict, rules: RowRules) -> dict:
    """What re-running a row takes from it, checked as data before anything runs: its key's
    parts (`parse_key`), a planner installed here, a protocol by name (never a file), and no
    option that names a program, a file or an address unless the person verifying named it
    on their own command line (`rules.given`), whose value then replaces the row's. A row
    that is malformed or forged is one `DynabarnError` line naming the row; a row this
    install cannot run (a planner not installed here, an option only the person verifying may
    name) comes back with `not_checked` (why) and `install` (what would let it run)."""
    where = f"{file}: row {number}"
    parts = parse_key(row["key"])
    parts["not_checked"], parts["install"] = "", ""
    if parts["protocol"] not in rules.protocols and (rules.protocol or {}).get("name") != parts["protocol"]:
        raise DynabarnError(
            f"{where}: protocol {parts['protocol']!r} is neither one of this package's ({', '.join(rules.protocols)})"
            " nor the folder's own (metadata.json)"
        )
    if parts["planner"] not in rules.planners:
        # Someone else's planner: nothing to run here, which is not a difference.
        parts["not_checked"] = f"planner {parts['planner']!r} is not installed here"
        parts["install"] = (
            f"name its code yourself: --planner {'PATH/' if '.py:' in parts['planner'] else ''}{parts['planner']}"
            if ":" in parts["planner"]
            else "install the package that provides it"
        )
        parts["given"] = []
        return parts
    code_problem = _code_problem(row, parts["planner"])
    if code_problem:
        raise DynabarnError(f"{where}: {code_problem}")
    external, given = rules.external_options(parts["planner"]), rules.given
    for option, value in parts["config"].items():
        if option in external and option not in given:
            parts["not_checked"] = (
                f"planner {parts['planner']} names {external[option]} ({option}={value!r:.60}); --verify never"
                f" takes that from a results file: to re-run it, name it yourself"
            )
            parts["install"] = give(option)
    # A row's own value for such an option is never kept, whether or not the row is run.
    parts["config"] = {
        k: given[k] if k in external else v for k, v in parts["config"].items() if k not in external or k in given
    }
    parts["given"] = sorted(k for k in parts["config"] if k in external)
    return parts


def _code_problem(row: dict, planner: str) -> str | None:
    """Why a row of a planner named by its code (`from_code`) may not run with the one the
    person verifying named: a file whose sha256 is not the row's."""
    from dynabarn.planners.from_code import LOADED

    code = LOADED.get(planner)
    if code is None or not code.file:
        return None
    recorded = row.get("planner_code")
    sha = recorded.get("sha256") if isinstance(recorded, dict) else None
    if sha != code.sha256:
        return (
            f"planner {planner}: {code.file} is not the file the row ran (sha256 {str(sha)[:12]}..., "
            f"here {code.sha256[:12]}...); --verify runs only the same code"
        )
    return None


GIVE = {"policy": "--policy FILE", "launch": "--ros-launch COMMAND"}
"""How the person verifying names an option a row may not supply (the rest: `--planner-config KEY=VALUE`)."""


def give(option: str) -> str:
    """The command-line option that names `option` for --verify."""
    return GIVE.get(option, f"--planner-config {option}=VALUE")


def world_roots(folder: Path, set_dir: Path | None = None) -> list[Path]:
    """Where a row's world file may be: inside the results folder, this package's world
    sets (the data root and the work root, where `make worlds`, the tiers and imports
    write), and the set the person verifying names (`--set`). Nothing a row says adds a
    place."""
    from dynabarn.provenance import DATA_ROOT, SHIPPED_WORLDS, work_root, worlds_dir

    roots = [folder, work_root(), DATA_ROOT, SHIPPED_WORLDS, worlds_dir()] + ([set_dir] if set_dir is not None else [])
    return list(dict.fromkeys(roots))


def row_world_file(row: dict, roots: list[Path], name: str) -> tuple[Path | None, str]:
    """The row's world file inside one of `roots`, with the row's bytes: (path, problem).
    The row's `world_file` is only a hint: a relative path without `..`, looked for under
    each root, and the key's file name directly in each."""
    from pathlib import PurePosixPath

    from dynabarn.world_file import MAX_WORLD_BYTES, world_sha256

    written = row.get("world_file")
    hints = []
    if isinstance(written, str) and "\x00" not in written and len(written) < 4096:
        hint = PurePosixPath(written)
        if not hint.is_absolute() and ".." not in hint.parts and hint.name == name:
            hints.append(hint)
    hints.append(PurePosixPath(name))
    shown = written if isinstance(written, str) else name
    other_bytes = ""  # a file of the name with other bytes: said only when no place has the row's
    for root in roots:
        inside = root.resolve()
        for hint in hints:
            path = root / hint
            try:
                if not path.is_file() or not path.resolve().is_relative_to(inside):
                    continue
                digest = world_sha256(path)
            except OSError:
                continue
            if digest is None:
                return None, f"world file {path} is larger than {MAX_WORLD_BYTES >> 20} MiB or not a regular file"
            if digest == row.get("world_sha256"):
                return path, ""
            # Another set's world of the same name (world_201.xml of the paper's 300 beside a
            # mixed set's): look on, as far as the set named with --set.
            other_bytes = other_bytes or f"world file {path} has other bytes than the row's (sha256 differs)"
    return None, other_bytes or (
        f"world file {str(shown)[:200]!r} is not on this machine inside the results folder or this package's world "
        "sets (generate or import it where the sweep ran, or name its set with --set)"
    )
