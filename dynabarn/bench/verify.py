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
from dynabarn.files import write_atomically
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


def parse_key(key: str) -> dict:
    """A row's key (`runner.EpisodeSpec.key`) as its parts: planner, config, world file
    name, protocol, seed and simulation settings."""
    try:
        planner, rest = key.split("|", 1)
        config, end = json.JSONDecoder().raw_decode(rest)
        parts = rest[end:].split("|")
        if parts[0] != "" or len(parts) < 4:
            raise ValueError("fields after the configuration")
        sim = {}
        if len(parts) > 4:
            if not parts[4].startswith("sim="):
                raise ValueError("the simulation settings")
            sim = json.loads(parts[4][4:])
        if not isinstance(config, dict) or not isinstance(sim, dict):
            raise ValueError("the configuration")
        return {
            "planner": planner,
            "config": config,
            "world": parts[1],
            "protocol": parts[2],
            "seed": int(parts[3]),
            "sim": sim,
        }
    except (ValueError, IndexError) as exc:
        raise DynabarnError(f"results row key {key[:80]!r} is not one dynabarn-bench writes ({exc})") from None


def _world_file(row: dict, folder: Path, name: str) -> tuple[Path | None, str]:
    """The row's world file on this machine, with its bytes: (path, problem)."""
    import hashlib

    from dynabarn.provenance import work_root

    written = Path(str(row.get("world_file", name)))
    candidates = [written, folder / written, work_root() / written]
    for path in candidates:
        if path.is_file() and path.name == name:
            if hashlib.sha256(path.read_bytes()).hexdigest() != row.get("world_sha256"):
                return None, f"world file {path} has other bytes than the row's (sha256 differs)"
            return path, ""
    return None, f"world file {written} is not on this machine (generate or import it where the sweep ran)"


def check_row(row: dict, folder: Path, protocol_dict: dict | None) -> RowCheck:
    """Re-run one row and compare it."""
    from dynabarn.protocol import EvalProtocol, get_protocol
    from dynabarn.recording import message_digest
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.sim_config import SimConfig

    key = row["key"]
    parts = parse_key(key)
    world, problem = _world_file(row, folder, parts["world"])
    if world is None:
        return RowCheck(key, False, problem=problem)
    if protocol_dict and protocol_dict.get("name") == parts["protocol"]:
        protocol = EvalProtocol.from_dict(protocol_dict)
    else:
        protocol = get_protocol(parts["protocol"])
    sim = SimConfig(**parts["sim"])
    spec = EpisodeSpec.make(
        world, parts["planner"], protocol, config=parts["config"], seed=parts["seed"], sim=sim, label=row["planner"]
    )
    with tempfile.TemporaryDirectory(prefix="dynabarn-verify-") as tmp:
        recording = Path(tmp) / "episode.mcap"
        try:
            now = run_spec(spec, record_to=recording).to_dict() | {"planner": spec.shown}
        except Exception as exc:  # a planner that no longer runs: that row does not reproduce
            return RowCheck(key, False, problem=f"the episode raised {type(exc).__name__}: {exc}")
        recorded = recording_path(row, folder)
        if recorded is not None:
            row = {**row, "recording_digest": message_digest(recorded)}
            now["recording_digest"] = message_digest(recording)
    shared = {k: row[k] for k in now if k in row}
    mismatches = compare(key, shared, {k: now[k] for k in shared})
    differences, notes = [], []
    for m in mismatches:
        added = _added_parameters(m.golden, m.now) if m.field == "planner_config" else None
        if added:
            notes.append(f"the planner now has parameters the row's version did not: {', '.join(added)}")
        else:
            differences.append({"key": key, "field": m.field, "old": m.golden, "new": m.now})
    return RowCheck(key, not differences, differences, notes=notes)


def _added_parameters(old: object, new: object) -> list[str] | None:
    """The parameters `new` has beyond `old` when they agree on every parameter `old` has
    (a planner that gained options with defaults since the row was written), else None."""
    if not isinstance(old, dict) or not isinstance(new, dict) or any(new.get(k, object()) != v for k, v in old.items()):
        return None
    return sorted(set(new) - set(old))


def _check(item: tuple[dict, str, dict | None]) -> RowCheck:
    row, folder, protocol = item
    return check_row(row, Path(folder), protocol)


def verify_results(path: Path, *, sample: int | None = DEFAULT_SAMPLE, jobs: int = 1, progress=None) -> dict:
    """Re-run a sample of the rows of the results at `path`; the verdict (also written to
    the folder's `verification.json` where it can be)."""
    from dynabarn.provenance import machine, versions

    file = results_file(path)
    rows = [r for r in read_results(file) if is_row(r) and isinstance(r.get("key"), str)]
    if not rows:
        raise DynabarnError(f"{file}: no results rows (not a results file of dynabarn-bench)")
    for r in rows:
        parse_key(r["key"])  # every key checked before anything runs: one clear line for a bad file
    folder = file.parent
    try:
        protocol = json.loads((folder / METADATA).read_text()).get("protocol")
    except (OSError, ValueError, AttributeError):
        protocol = None
    chosen = sample_rows([r for r in rows if r.get("outcome") != "error"], sample)
    items = [(r, str(folder), protocol if isinstance(protocol, dict) else None) for r in chosen]
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
