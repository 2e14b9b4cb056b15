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
from dynabarn.bench.row_rules import RowRules, give, row_inputs, row_world_file, world_roots
from dynabarn.errors import DynabarnError, NotInstalledHere
from dynabarn.files import plain_name_problem, write_atomically
from dynabarn.planners.from_code import LOADED, CodePlanner, load_again
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
    not_checked: str = ""
    """Why this install cannot run the row (an extra, a ROS stack, a planner or an option it
    lacks): neither identical nor a difference."""
    install: str = ""
    """What would let it run here (a command, or the option to give)."""


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


def check_row(row: dict, parts: dict, folder: Path, roots: list[Path], protocol_dict: dict | None) -> RowCheck:
    """Re-run one row, whose inputs `row_inputs` checked (`parts`), and compare it."""
    from dynabarn.protocol import EvalProtocol, get_protocol
    from dynabarn.recording import message_digest
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.sim_config import SimConfig

    key = row["key"]
    if parts["not_checked"]:
        return RowCheck(key, False, not_checked=parts["not_checked"], install=parts["install"])
    world, problem = row_world_file(row, roots, parts["world"])
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
            now = run_spec(spec, record_to=recording).result.to_dict() | {"planner": spec.shown}
        except NotInstalledHere as exc:  # this install lacks what the row needs: not a difference
            return RowCheck(key, False, not_checked=str(exc), install=exc.install)
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
        old = _scored_before_the_static_fix(m.golden, m.now, world) if m.field == "tracking" else None
        added = _added_parameters(old or m.golden, m.now) if m.field in ADDED_NOTES else None
        if m.field == "planner_config" and parts["given"] and _same_but(m.golden, m.now, parts["given"]):
            notes.append(f"given on the command line in place of the rows' values: {', '.join(parts['given'])}")
        elif added is not None and (added or old):
            notes += [STATIC_FIX_NOTE] if old else []
            notes += [f"{ADDED_NOTES[m.field]}: {', '.join(added)}"] if added else []
        else:
            differences.append({"key": key, "field": m.field, "old": m.golden, "new": m.now})
    return RowCheck(key, not differences, differences, notes=notes)


STATIC_FIX_NOTE = (
    "tracking recall of a world with a static field, scored before issue 57's fix (obstacles hidden behind "
    "standing cylinders counted as in view): compared without it"
)


def _scored_before_the_static_fix(old: object, new: object, world: Path) -> dict | None:
    """A row's tracking written before the scorer counted CLEAR-MOT switches (no
    `id_switches_mot`), of a world with standing cylinders, that differs from the re-run in
    recall alone: the row's tracking with the re-run's recall (the fix of commit 029ae81 changed
    which obstacles are in view behind the static field, and so the recall, nothing else); None
    otherwise, so that every other difference stays one."""
    from dynabarn.mjcf import read_world

    if not isinstance(old, dict) or not isinstance(new, dict) or "id_switches_mot" in old or "recall" not in new:
        return None
    if old.get("recall") == new["recall"] or not read_world(world).layout.cylinders:
        return None
    return old | {"recall": new["recall"]}


ADDED_NOTES = {
    "planner_config": "the planner now has parameters the row's version did not",
    "tracking": "the episode now reports tracking measures the row's version did not",
}
"""Fields where a re-run that agrees on everything the row has and adds entries is the same
episode, a note rather than a difference: a planner's new options with their defaults, the
scorer's new measures (`sim/track_scoring.py`)."""


def _same_but(old: object, new: object, left_out: list[str]) -> bool:
    """Two configurations agree on everything but the options `left_out`."""
    if not isinstance(old, dict) or not isinstance(new, dict):
        return False
    return {k: v for k, v in old.items() if k not in left_out} == {k: v for k, v in new.items() if k not in left_out}


def _added_parameters(old: object, new: object) -> list[str] | None:
    """The entries `new` has beyond `old` when they agree on every entry `old` has (a planner
    that gained options with defaults, or a scorer that gained measures, since the row was
    written), else None."""
    if not isinstance(old, dict) or not isinstance(new, dict) or any(new.get(k, object()) != v for k, v in old.items()):
        return None
    return sorted(set(new) - set(old))


def _check(item: tuple[dict, dict, str, list[str], dict | None, CodePlanner | None]) -> RowCheck:
    row, parts, folder, roots, protocol, code = item
    if code is not None:  # a planner from code that the person verifying named: the same file here
        try:
            load_again(code)
        except DynabarnError as exc:
            return RowCheck(row["key"], False, problem=str(exc))
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
    code: set[str] = frozenset(),
) -> dict:
    """Re-run a sample of the rows of the results at `path`; the verdict (also written to
    the folder's `verification.json` where it can be).

    The rows are data: every row's inputs are checked before anything runs (`row_inputs`);
    `given` holds the options the person verifying names on their own command line (a
    policy file, a launch command), the only source of options that name a program, a file
    or an address; `set_dir` a further folder the world files may be in (`world_roots`);
    `code` the planners from code (`from_code`) they named, the only ones that run."""
    from dynabarn.provenance import machine, versions

    given = dict(given or {})
    file = results_file(path)
    rows = [r for r in read_results(file) if is_row(r)]
    if not rows:
        raise DynabarnError(f"{file}: no results rows (not a results file of dynabarn-bench)")
    folder = file.parent
    protocol = _folder_protocol(folder)
    # Every row checked before anything runs: one clear line for a bad or forged file.
    rules = RowRules.here(protocol, given, code)
    inputs = [row_inputs(file, i + 1, r, rules) for i, r in enumerate(rows)]
    named = {o for p in inputs if p["planner"] in rules.planners for o in p["given"]}
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
    items = [
        (r, by_key[r["key"]], str(folder), roots, protocol, LOADED.get(by_key[r["key"]]["planner"])) for r in chosen
    ]
    checks = list((progress or (lambda it, total: it))(map_in_workers(_check, items, jobs), len(items)))
    order = {r["key"]: i for i, r in enumerate(chosen)}
    checks.sort(key=lambda c: order[c.key])
    notes = _version_notes(chosen, versions(), machine())
    ran = [c for c in checks if not c.not_checked]
    lacking = missing_extras()
    verdict = {
        "format": "dynabarn-verification",
        "results": str(file),
        "when": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "sample": "all" if sample is None else sample,
        "checked": len(ran),
        "identical": sum(c.identical for c in ran),
        "not_checked": len(checks) - len(ran),
        "ok": all(c.identical for c in ran),
        # A verdict on everything sampled, by an install with every extra: the only kind the
        # documentation site shows (a local one that skipped rows says nothing of them).
        "complete": len(ran) == len(checks) and not lacking,
        "missing_extras": lacking,
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


EXTRA_MODULES = {"learn": "torch", "ros": "rosbags", "ray": "ray"}
"""The extras whose absence leaves rows unchecked, each by a module it installs."""


def missing_extras() -> list[str]:
    """The extras (`EXTRA_MODULES`) this install lacks."""
    import importlib.util

    return [extra for extra, module in EXTRA_MODULES.items() if importlib.util.find_spec(module) is None]


def exit_code(verdict: dict) -> int:
    """0: every row re-run reproduced and none was left unchecked; 1: a row differs;
    3: nothing differs, but some rows could not be checked here (`NOT_CHECKED_EXIT`)."""
    if not verdict["ok"]:
        return 1
    return NOT_CHECKED_EXIT if verdict.get("not_checked") else 0


NOT_CHECKED_EXIT = 3


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
