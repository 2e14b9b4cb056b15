"""The results folder: `results.jsonl` (one flushed, fsync'ed line per finished episode:
full metrics, versions, world hash) and `metadata.json` (what the sweep was)."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
from pathlib import Path

from dynabarn.bench.jobs import Job
from dynabarn.errors import DynabarnError

RESULTS = "results.jsonl"
METADATA = "metadata.json"


def read_results(path: Path) -> list[dict]:
    """Rows of a results.jsonl; a last line cut by a crash is ignored."""
    rows = []
    if not path.is_file():
        return rows
    with path.open() as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue  # a line half-written when the process died
    return rows


def append_row(f, row: dict) -> None:
    f.write(json.dumps(row, sort_keys=True) + "\n")
    f.flush()
    os.fsync(f.fileno())


def metadata(args_dict: dict, jobs: list[Job]) -> dict:
    from dynabarn.provenance import versions

    world_hashes = sorted({hashlib.sha256(Path(j.world_file).read_bytes()).hexdigest()[:16] for j in jobs})
    return {
        "format": "dynabarn-bench",
        "versions": versions(),
        "python": sys.version.split()[0],
        "arguments": args_dict,
        "protocol": jobs[0].protocol if jobs else None,
        "planners": sorted({j.planner for j in jobs}),
        "episodes": len(jobs),
        "worlds_digest": hashlib.sha256("".join(world_hashes).encode()).hexdigest()[:16],
    }


def check_or_write_metadata(out_dir: Path, meta: dict, *, force: bool) -> None:
    """Refuse to mix sweeps in one folder: same planners/protocol/worlds, or --force."""
    path = out_dir / METADATA
    out_dir.mkdir(parents=True, exist_ok=True)
    meta = json.loads(json.dumps(meta))  # compare as stored (tuples become lists)
    if path.is_file() and not force:
        old = json.loads(path.read_text())
        for key in ("protocol", "worlds_digest"):
            if old.get(key) != meta.get(key):
                raise DynabarnError(f"{out_dir} holds a different sweep ({key} differs); use another --out or --force")
    elif path.is_file() and force:
        for name in (RESULTS, "summary.csv", "summary.md", "fig5.png"):
            (out_dir / name).unlink(missing_ok=True)
        shutil.rmtree(out_dir / "recordings", ignore_errors=True)
    path.write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n")


def jsonable_args(args) -> dict:
    d = dict(vars(args))
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in d.items()}
