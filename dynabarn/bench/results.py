"""The results folder: `results.jsonl` (one flushed, fsync'ed line per finished episode:
full metrics, versions, world hash) and `metadata.json` (what the sweep was)."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path

from dynabarn.bench.jobs import Job
from dynabarn.errors import DynabarnError
from dynabarn.files import folder_lock, write_atomically
from dynabarn.metrics import OUTCOMES, numbers_ok

RESULTS = "results.jsonl"
METADATA = "metadata.json"
WORLDS = "worlds.json"
LOCK = ".lock"


def read_results(path: Path) -> list[dict]:
    """Rows of a results.jsonl; a line cut by a crash, or anything that is not a row, is ignored."""
    return _read(path)[0]


RECORDINGS = "recordings"
"""A sweep's recordings (`--record`), in its folder."""
MAX_ROW_BYTES = 1 << 20
"""A row is a few kB (with a planner's traceback, tens); a longer line is not one of ours."""
_ROW_TEXT = ("key", "planner", "difficulty", "outcome")
"""Text fields every row has (a worker that died mid-episode leaves a row without `world`)."""


def is_row(row: object) -> bool:
    """Whether a parsed line is a result row the summaries can use: the identifying fields
    as text, an outcome the runner gives, the seed a whole number, every metric a number or
    null. Anything else (a foreign line, a row edited by hand) is left out."""
    if not isinstance(row, dict) or not all(isinstance(row.get(k), str) for k in _ROW_TEXT):
        return False
    if row["outcome"] not in OUTCOMES or not (isinstance(row.get("seed"), int) and not isinstance(row["seed"], bool)):
        return False
    if not isinstance(row.get("world", ""), str):
        return False
    return numbers_ok(row)


def _lines(f) -> Iterator[str | None]:
    """The file's lines, None for one longer than MAX_ROW_BYTES (read past, never held)."""
    while line := f.readline(MAX_ROW_BYTES):
        if len(line) == MAX_ROW_BYTES and not line.endswith("\n"):
            while (rest := f.readline(MAX_ROW_BYTES)) and not rest.endswith("\n"):
                pass
            yield None
            continue
        yield line


def _read(path: Path) -> tuple[list[dict], bool]:
    """(rows, clean): clean is False when some line was not a row (torn or foreign)."""
    rows: list[dict] = []
    clean = True
    if not path.is_file():
        return rows, clean
    with path.open(encoding="utf-8", errors="replace") as f:
        for line in _lines(f):
            if line is not None and not line.strip():
                continue
            try:
                row = json.loads(line) if line is not None else None
            except (ValueError, RecursionError):
                clean = False  # a line half-written when the process died
                continue
            if is_row(row):
                rows.append(row)
            else:
                clean = False
    return rows, clean


def append_row(f, row: dict) -> None:
    f.write(json.dumps(row, sort_keys=True, allow_nan=False) + "\n")
    f.flush()
    os.fsync(f.fileno())


def prepare_resume(path: Path) -> list[dict]:
    """The finished rows to keep, before a sweep (re)starts: torn lines dropped, rows of
    infrastructure failures (`retry`: disk full, a killed worker) left out so they run again,
    and a row per key. The file is rewritten (atomically) only when something was dropped."""
    rows, clean = _read(path)
    keep: dict[str, dict] = {}
    for row in rows:
        if not row.get("retry"):
            keep.setdefault(row["key"], row)
    if not clean or len(keep) != len(rows):
        write_atomically(path, "".join(json.dumps(r, sort_keys=True) + "\n" for r in keep.values()))
    return list(keep.values())


@contextlib.contextmanager
def locked(out_dir: Path):
    """Hold `out_dir/.lock` (flock) while writing there, so a second sweep into the same
    folder stops with one line instead of writing every row twice. Re-entrant in a process."""
    busy = "{folder} is being written by another dynabarn-bench or -demos (pid {pid}); wait for it or use another --out"
    with folder_lock(out_dir, LOCK, busy=busy):
        yield


def metadata(args_dict: dict, jobs: list[Job], argv: list[str] | None = None) -> dict:
    """What this sweep is (protocol, worlds, simulation settings: the folder's identity) and
    this invocation of it (`invocation`: the command line, versions, machine, time, its
    planners and episodes); `check_or_write_metadata` keeps every invocation's."""
    from datetime import UTC, datetime

    from dynabarn.provenance import machine, versions

    world_hashes = sorted({hashlib.sha256(Path(j.spec.world).read_bytes()).hexdigest()[:16] for j in jobs})
    settings = dict(jobs[0].spec.sim) if jobs else {}
    planners = sorted({j.shown for j in jobs})
    return {
        "format": "dynabarn-bench",
        "versions": versions(),
        "python": sys.version.split()[0],
        "arguments": args_dict,
        "protocol": jobs[0].spec.protocol if jobs else None,
        "planners": planners,
        "episodes": len(jobs),
        "worlds_digest": hashlib.sha256("".join(world_hashes).encode()).hexdigest()[:16],
        **({"sim": settings} if settings else {}),  # the simulation's settings, when not the defaults
        "invocation": {
            "when": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "command": ["dynabarn-bench", *(sys.argv[1:] if argv is None else argv)],
            "arguments": args_dict,
            "versions": versions(),
            "python": sys.version.split()[0],
            "machine": {
                **{k: v for k, v in machine().items() if k in ("cpu", "arch")},
                "cores": os.cpu_count(),
                "system": platform.platform(),
            },
            "planners": planners,
            "episodes": len(jobs),
        },
    }


def invocations_of(meta: dict) -> list[dict]:
    """Every invocation a folder's metadata records; a metadata.json from before they were
    kept counts as one invocation, marked as recovered from it."""
    kept = meta.get("invocations")
    if isinstance(kept, list):
        return [i for i in kept if isinstance(i, dict)]
    if not isinstance(meta.get("arguments"), dict):
        return []
    return [
        {
            "when": None,
            "arguments": meta.get("arguments"),
            "versions": meta.get("versions"),
            "python": meta.get("python"),
            "planners": meta.get("planners"),
            "episodes": meta.get("episodes"),
            "recovered": "from a metadata.json that kept only its last invocation",
        }
    ]


def check_or_write_metadata(out_dir: Path, meta: dict, *, force: bool) -> None:
    """Refuse to mix sweeps in one folder: same protocol, worlds and simulation settings,
    or --force. The folder's metadata keeps every invocation that wrote into it
    (`invocations`), and `planners` names every planner any of them ran."""
    path = out_dir / METADATA
    out_dir.mkdir(parents=True, exist_ok=True)
    meta = json.loads(json.dumps(meta))  # compare as stored (tuples become lists)
    invocation = meta.pop("invocation", None)
    earlier: list[dict] = []
    if path.is_file() and not force:
        try:
            old = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError, RecursionError):
            old = None
        if not isinstance(old, dict):
            raise DynabarnError(f"{path} is not a sweep's metadata; use another --out, or --force to start over")
        for key in ("protocol", "worlds_digest", "sim"):
            if old.get(key) != meta.get(key):
                raise DynabarnError(f"{out_dir} holds a different sweep ({key} differs); use another --out or --force")
        earlier = invocations_of(old)
    elif path.is_file() and force:
        for name in (RESULTS, WORLDS, "summary.csv", "summary.md", "fig5.png"):
            (out_dir / name).unlink(missing_ok=True)
        shutil.rmtree(out_dir / RECORDINGS, ignore_errors=True)
    invocations = earlier + ([invocation] if invocation else [])
    meta["invocations"] = invocations
    meta["planners"] = sorted(
        {p for i in invocations for p in (i.get("planners") or []) if isinstance(p, str)} | set(meta["planners"])
    )
    write_atomically(path, json.dumps(meta, indent=1, sort_keys=True) + "\n")


def jsonable_args(args) -> dict:
    d = {k: v for k, v in vars(args).items() if k != "argv"}  # the command line is the invocation's
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in d.items()}


def write_worlds(out_dir: Path, jobs: list[Job]) -> Path:
    """`OUT/worlds.json`: each world of the sweep with its index entry's difficulty class,
    obstacle count and measured difficulty, and whether its provenance is the paper's
    (`worldset.paper_world_ids`), so results can be related to the worlds without their
    folder (the imported release worlds are not part of a checkout); and under `profiles`
    each profile set the worlds were drawn from, as their index records it (with its
    file's name and sha256, or the options, for a user's profile)."""
    from dynabarn.worldset import paper_world_ids, read_index

    path = Path(out_dir) / WORLDS
    old: dict = {}
    old_profiles: dict = {}
    if path.is_file():
        try:
            stored = json.loads(path.read_text())
            old = {w["name"]: w for w in stored["worlds"]}
            old_profiles = dict(stored.get("profiles", {}))
        except (json.JSONDecodeError, UnicodeDecodeError, RecursionError, KeyError, TypeError, ValueError):
            old, old_profiles = {}, {}
    worlds = dict(old)
    profiles = dict(old_profiles)
    files = {(Path(j.spec.world).parent, Path(j.spec.world).name) for j in jobs}  # once, not per entry
    for folder in sorted({folder for folder, _ in files}):
        try:
            index = read_index(folder)
        except DynabarnError:
            continue
        entries, paper = index["worlds"], paper_world_ids(index)
        drawn_from = index.get("profile_set")
        if isinstance(drawn_from, dict) and isinstance(drawn_from.get("name"), str):
            profiles[drawn_from["name"]] = {"profile_set": drawn_from} | (
                {"source": index["profile_source"]} if "profile_source" in index else {}
            )
        for e in entries:
            name = e.get("name") or Path(e["file"]).stem
            if (folder, e["file"]) in files:
                worlds[name] = {
                    "name": name,
                    "id": e["id"],
                    "difficulty": e.get("difficulty"),
                    "n_obstacles": e.get("n_obstacles"),
                    "measured": e.get("measured"),
                    "sha256": e.get("sha256"),
                    "paper": e["id"] in paper,
                    **({"profile_set": e["profile_set"]} if e.get("profile_set") else {}),
                    **_certificates(e),
                }
    if worlds != old or profiles != old_profiles:
        stored = {"worlds": [worlds[k] for k in sorted(worlds)]} | ({"profiles": profiles} if profiles else {})
        text = json.dumps(stored, indent=1, sort_keys=True) + "\n"
        write_atomically(path, text)
    return path


def _certificates(entry: dict) -> dict:
    """An index entry's certificates, short: per protocol, whether every trial is certified,
    the seeds that are, and the witnesses' slack (`bench.certify`)."""
    from dynabarn.worldset import own_certificates

    short = {
        protocol: {
            "certified": bool(r.get("certified")),
            "seeds": [t["seed"] for t in r.get("trials", [])],
            "certified_seeds": [t["seed"] for t in r.get("trials", []) if t.get("certified")],
            **({"slack": r["slack"]} if "slack" in r else {}),
        }
        for protocol, r in own_certificates(entry).items()
    }
    return {"certificates": short} if short else {}


def certified_episodes(out_dir: Path) -> dict[tuple[str, str], tuple[set[int], set[int]]]:
    """(world name, protocol) -> (seeds certified, seeds with a certificate), from the
    results folder's worlds.json; empty when no world of it has a certificate."""
    path = Path(out_dir) / WORLDS
    try:
        worlds = json.loads(path.read_text())["worlds"]
        return {
            (w["name"], protocol): (set(c["certified_seeds"]), set(c["seeds"]))
            for w in worlds
            for protocol, c in w.get("certificates", {}).items()
        }
    except (OSError, json.JSONDecodeError, UnicodeDecodeError, RecursionError, KeyError, TypeError, AttributeError):
        return {}


def recording_path(row: dict, out_dir: Path) -> Path | None:
    """A row's recording on this machine, or None: its path is written relative to where the
    sweep ran (or absolute), and the folder may have moved since, so it is also looked for
    under the folder and in the folder's RECORDINGS. Only a regular file inside the folder
    is taken: a row is data, and never makes a command open a file elsewhere."""
    written = row.get("recording")
    if not isinstance(written, str) or not written or "\x00" in written or len(written) > 4096:
        return None
    out = Path(out_dir)
    relative = not Path(written).is_absolute() and ".." not in Path(written).parts
    candidates = ((Path(written), out / written) if relative else ()) + (out / RECORDINGS / Path(written).name,)
    try:
        inside = out.resolve()
        for c in candidates:
            if c.is_file() and not c.is_symlink() and c.resolve().is_relative_to(inside):
                return c
    except (OSError, ValueError):
        pass
    return None


def paper_worlds(out_dir: Path) -> set[str]:
    """Names of the results folder's worlds whose provenance is the paper's (empty without
    a `worlds.json` that says so: then nothing is compared with the paper)."""
    path = Path(out_dir) / WORLDS
    try:
        return {w["name"] for w in json.loads(path.read_text())["worlds"] if w.get("paper") is True}
    except (OSError, json.JSONDecodeError, UnicodeDecodeError, RecursionError, KeyError, TypeError):
        return set()
