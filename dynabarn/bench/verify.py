"""`dynabarn-bench --verify RESULTS`: re-run rows of anyone's results file and compare.

Every episode is deterministic, so a row of a `results.jsonl` names everything needed to
run it again: its key holds the planner, the configuration it was given, the world file's
name, the protocol, the seed and any changed simulation settings; the row holds the world
file's path and sha256. A sample of rows (drawn by a fixed seed, or all) is re-run on this
machine and compared field by field, as the golden set is (`golden.compare`: every field
but the machine's), plus the recording's message digest where the row's recording is at
hand. A world file that is not on this machine, or not with the row's bytes, is reported
as such (it is not the same episode). The verdict is written into the folder
(`verification.json`, shown by its `report.html`) when the folder can be written.
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from dynabarn.bench.golden import compare
from dynabarn.bench.results import METADATA, RESULTS, is_row, read_results, recording_path
from dynabarn.errors import DynabarnError
from dynabarn.files import plain_name_problem, write_atomically
from dynabarn.limits import MAX_SEED
from dynabarn.processes import map_in_workers

DEFAULT_SAMPLE = 20
VERIFICATION = "verification.json"
"""Where the verdict is written, beside the rows (the folder's report shows it)."""
SAMPLE_SEED = 20260
"""The sample is the same on every machine: rows drawn by this seed from the file's order."""


@dataclass
class RowCheck:
    key: str
    identical: bool
    differences: list[dict] = field(default_factory=list)
    problem: str = ""
    """Why the row could not be re-run as it was (world file missing or changed)."""
    notes: list[str] = field(default_factory=list)


def results_file(path: Path) -> Path:
    """The results file named by `path` (the file, or the folder holding it)."""
    path = Path(path)
    file = path / RESULTS if path.is_dir() else path
    if not file.is_file():
        raise DynabarnError(f"{path}: no results file (a dynabarn-bench folder or its {RESULTS})")
    return file


def sample_rows(rows: list[dict], sample: int | None) -> list[dict]:
    """`sample` rows (None: all) drawn without replacement by `SAMPLE_SEED`, in file order."""
    import numpy as np

    if sample is None or sample >= len(rows):
        return list(rows)
    chosen = np.random.default_rng(SAMPLE_SEED).choice(len(rows), size=sample, replace=False)
    return [rows[i] for i in sorted(chosen)]


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
        for what, name in (("planner", planner.partition("@")[0]), ("protocol", parts[2]), ("world file", parts[1])):
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
    def here(cls, protocol: dict | None, given: dict) -> RowRules:
        from dynabarn.planners import available_planners
        from dynabarn.protocol import PROTOCOLS

        return cls(set(available_planners()), PROTOCOLS.names(), protocol, dict(given))

    def external_options(self, planner: str) -> dict[str, str]:
        from dynabarn.planners.registry import external_options

        if planner not in self.external:
            self.external[planner] = external_options(planner)
        return self.external[planner]


def row_inputs(file: Path, number: int, row: dict, rules: RowRules) -> dict:
    """What re-running a row takes from it, checked as data before anything runs: its key's
    parts (`parse_key`), a planner installed here, a protocol by name (never a file), and no
    option that names a program, a file or an address unless the person verifying named it
    on their own command line (`rules.given`), whose value then replaces the row's. One
    `DynabarnError` line naming the row otherwise."""
    where = f"{file}: row {number}"
    parts = parse_key(row["key"])
    if parts["planner"] not in rules.planners:
        raise DynabarnError(f"{where}: planner {parts['planner']!r} is not installed here; --verify runs only those")
    if parts["protocol"] not in rules.protocols and (rules.protocol or {}).get("name") != parts["protocol"]:
        raise DynabarnError(
            f"{where}: protocol {parts['protocol']!r} is neither one of this package's ({', '.join(rules.protocols)})"
            " nor the folder's own (metadata.json)"
        )
    external, given = rules.external_options(parts["planner"]), rules.given
    for option, value in parts["config"].items():
        if option in external and option not in given:
            raise DynabarnError(
                f"{where}: planner {parts['planner']} names {external[option]} ({option}={value!r:.60}); --verify never"
                f" takes that from a results file: to re-run it, name it yourself ({give(option)})"
            )
    parts["config"] = {k: given.get(k, v) if k in external else v for k, v in parts["config"].items()}
    parts["given"] = sorted(k for k in parts["config"] if k in external)
    return parts


GIVE = {"policy": "--policy FILE", "launch": "--ros-launch COMMAND"}
"""How the person verifying names an option a row may not supply (the rest: `--planner-config KEY=VALUE`)."""


def give(option: str) -> str:
    """The command-line option that names `option` for --verify."""
    return GIVE.get(option, f"--planner-config {option}=VALUE")


def _file_sha256(path: Path, limit: int) -> str | None:
    """sha256 of a regular file of at most `limit` bytes, read in pieces (a 40 GB sparse file
    is refused by its size, never read whole); None when it is larger or not a regular file."""
    import hashlib
    import os
    import stat

    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0))
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_size > limit:
            return None
        digest, read = hashlib.sha256(), 0
        while piece := f.read(1 << 20):
            read += len(piece)
            if read > limit:
                return None
            digest.update(piece)
    return digest.hexdigest()


def world_roots(folder: Path, set_dir: Path | None = None) -> list[Path]:
    """Where a row's world file may be: inside the results folder, this package's world
    sets (the data root and the work root, where `make worlds`, the tiers and imports
    write), and the set the person verifying names (`--set`). Nothing a row says adds a
    place."""
    from dynabarn.provenance import DATA_ROOT, SHIPPED_WORLDS, work_root, worlds_dir

    roots = [folder, work_root(), DATA_ROOT, SHIPPED_WORLDS, worlds_dir()] + ([set_dir] if set_dir is not None else [])
    return list(dict.fromkeys(roots))


def _world_file(row: dict, roots: list[Path], name: str) -> tuple[Path | None, str]:
    """The row's world file inside one of `roots`, with the row's bytes: (path, problem).
    The row's `world_file` is only a hint: a relative path without `..`, looked for under
    each root, and the key's file name directly in each."""
    from pathlib import PurePosixPath

    from dynabarn.world_file import MAX_WORLD_BYTES

    written = row.get("world_file")
    hints = []
    if isinstance(written, str) and "\x00" not in written and len(written) < 4096:
        hint = PurePosixPath(written)
        if not hint.is_absolute() and ".." not in hint.parts and hint.name == name:
            hints.append(hint)
    hints.append(PurePosixPath(name))
    shown = written if isinstance(written, str) else name
    for root in roots:
        inside = root.resolve()
        for hint in hints:
            path = root / hint
            try:
                if not path.is_file() or not path.resolve().is_relative_to(inside):
                    continue
                digest = _file_sha256(path, MAX_WORLD_BYTES)
            except OSError:
                continue
            if digest is None:
                return None, f"world file {path} is larger than {MAX_WORLD_BYTES >> 20} MiB or not a regular file"
            if digest != row.get("world_sha256"):
                return None, f"world file {path} has other bytes than the row's (sha256 differs)"
            return path, ""
    return None, (
        f"world file {str(shown)[:200]!r} is not on this machine inside the results folder or this package's world "
        "sets (generate or import it where the sweep ran, or name its set with --set)"
    )


def check_row(row: dict, parts: dict, folder: Path, roots: list[Path], protocol_dict: dict | None) -> RowCheck:
    """Re-run one row, whose inputs `row_inputs` checked (`parts`), and compare it."""
    from dynabarn.protocol import EvalProtocol, get_protocol
    from dynabarn.recording import message_digest
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.sim_config import SimConfig

    key = row["key"]
    world, problem = _world_file(row, roots, parts["world"])
    if world is None:
        return RowCheck(key, False, problem=problem)
    if protocol_dict and protocol_dict.get("name") == parts["protocol"]:
        protocol = EvalProtocol.from_dict(protocol_dict)
    else:
        protocol = get_protocol(parts["protocol"])  # a registered name: row_inputs checked it
    spec = EpisodeSpec.make(
        world,
        parts["planner"],
        protocol,
        config=parts["config"],
        seed=parts["seed"],
        sim=SimConfig(**parts["sim"]),
        label=row["planner"],
    )
    with tempfile.TemporaryDirectory(prefix="dynabarn-verify-") as tmp:
        recording = Path(tmp) / "episode.mcap"
        try:
            now = run_spec(spec, record_to=recording).to_dict() | {"planner": spec.shown}
        except Exception as exc:  # a planner that no longer runs: that row does not reproduce
            return RowCheck(key, False, problem=f"the episode raised {type(exc).__name__}: {exc}")
        recorded = recording_path(row, folder)
        if recorded is not None:
            try:
                row = {**row, "recording_digest": message_digest(recorded)}
                now["recording_digest"] = message_digest(recording)
            except DynabarnError as exc:  # the folder's recording is damaged: say so beside the row
                return RowCheck(key, False, problem=f"its recording {recorded.name} cannot be read ({exc})")
    shared = {k: row[k] for k in now if k in row}
    mismatches = compare(key, shared, {k: now[k] for k in shared})
    differences, notes = [], []
    for m in mismatches:
        added = _added_parameters(m.golden, m.now) if m.field == "planner_config" else None
        if m.field == "planner_config" and parts["given"] and _same_but(m.golden, m.now, parts["given"]):
            notes.append(f"given on the command line in place of the rows' values: {', '.join(parts['given'])}")
        elif added:
            notes.append(f"the planner now has parameters the row's version did not: {', '.join(added)}")
        else:
            differences.append({"key": key, "field": m.field, "old": m.golden, "new": m.now})
    return RowCheck(key, not differences, differences, notes=notes)


def _same_but(old: object, new: object, left_out: list[str]) -> bool:
    """Two configurations agree on everything but the options `left_out`."""
    if not isinstance(old, dict) or not isinstance(new, dict):
        return False
    return {k: v for k, v in old.items() if k not in left_out} == {k: v for k, v in new.items() if k not in left_out}


def _added_parameters(old: object, new: object) -> list[str] | None:
    """The parameters `new` has beyond `old` when they agree on every parameter `old` has
    (a planner that gained options with defaults since the row was written), else None."""
    if not isinstance(old, dict) or not isinstance(new, dict) or any(new.get(k, object()) != v for k, v in old.items()):
        return None
    return sorted(set(new) - set(old))


def _check(item: tuple[dict, dict, str, list[str], dict | None]) -> RowCheck:
    row, parts, folder, roots, protocol = item
    return check_row(row, parts, Path(folder), [Path(r) for r in roots], protocol)


def _folder_protocol(folder: Path) -> dict | None:
    """The protocol the folder's metadata.json holds, when it is a well-formed one."""
    from dynabarn.protocol import EvalProtocol

    try:
        protocol = json.loads((folder / METADATA).read_text()).get("protocol")
        EvalProtocol.from_dict(protocol)
    except (OSError, ValueError, AttributeError, TypeError, RecursionError, DynabarnError):
        return None
    return protocol if isinstance(protocol, dict) and plain_name_problem(protocol.get("name")) is None else None


def verify_results(
    path: Path,
    *,
    sample: int | None = DEFAULT_SAMPLE,
    jobs: int = 1,
    progress=None,
    given: dict | None = None,
    set_dir: Path | None = None,
) -> dict:
    """Re-run a sample of the rows of the results at `path`; the verdict (also written to
    the folder's `verification.json` where it can be).

    The rows are data: every row's inputs are checked before anything runs (`row_inputs`);
    `given` holds the options the person verifying names on their own command line (a
    policy file, a launch command), the only source of options that name a program, a file
    or an address; `set_dir` a further folder the world files may be in (`world_roots`)."""
    from dynabarn.provenance import machine, versions

    given = dict(given or {})
    file = results_file(path)
    rows = [r for r in read_results(file) if is_row(r)]
    if not rows:
        raise DynabarnError(f"{file}: no results rows (not a results file of dynabarn-bench)")
    folder = file.parent
    protocol = _folder_protocol(folder)
    # Every row checked before anything runs: one clear line for a bad or forged file.
    rules = RowRules.here(protocol, given)
    inputs = [row_inputs(file, i + 1, r, rules) for i, r in enumerate(rows)]
    named = {o for p in inputs for o in p["config"] if o in rules.external_options(p["planner"])}
    unused = sorted(set(given) - named)
    if unused:
        raise DynabarnError(
            f"{', '.join(give(o).split()[0] for o in unused)} ({', '.join(unused)}): no row of {file} has such an "
            "option naming a program, a file or an address; "
            "with --verify, give only those the rows need"
        )
    by_key = {r["key"]: p for r, p in zip(rows, inputs, strict=True)}
    chosen = sample_rows([r for r in rows if r.get("outcome") != "error"], sample)
    roots = [str(r) for r in world_roots(folder, set_dir)]
    items = [(r, by_key[r["key"]], str(folder), roots, protocol) for r in chosen]
    checks = list((progress or (lambda it, total: it))(map_in_workers(_check, items, jobs), len(items)))
    order = {r["key"]: i for i, r in enumerate(chosen)}
    checks.sort(key=lambda c: order[c.key])
    notes = _version_notes(chosen, versions(), machine())
    verdict = {
        "format": "dynabarn-verification",
        "results": str(file),
        "when": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "sample": "all" if sample is None else sample,
        "checked": len(checks),
        "identical": sum(c.identical for c in checks),
        "ok": all(c.identical for c in checks),
        "rows": [asdict(c) for c in checks],
        "differences": [d for c in checks for d in c.differences]
        + [{"key": c.key, "field": "-", "old": "", "new": c.problem} for c in checks if c.problem],
        "notes": notes + sorted({n for c in checks for n in c.notes}),
    }
    try:
        write_atomically(folder / VERIFICATION, json.dumps(verdict, indent=1, default=str) + "\n")
    except OSError:
        verdict["notes"].append(f"{folder} is read-only: the verdict was not written there")
    return verdict


def _version_notes(rows: list[dict], now_versions: dict, now_machine: dict) -> list[str]:
    """Where the rows' versions or machine differ from this one's: the likely explanation
    of a difference, printed beside it."""
    notes = []
    for name, value in sorted(now_versions.items()):
        then = sorted({str((r.get("versions") or {}).get(name)) for r in rows})
        if then != [str(value)]:
            notes.append(f"versions differ: {name} {', '.join(then)} in the rows, {value} here")
    for name in ("cpu", "arch", "python"):
        then = sorted({str((r.get("machine") or {}).get(name)) for r in rows})
        if then != [str(now_machine.get(name))]:
            notes.append(f"machine differs: {name} {', '.join(then)} in the rows, {now_machine.get(name)} here")
    return notes
