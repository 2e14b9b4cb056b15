"""The report's data, built from a results folder: every episode as columns (what the grid,
the episode panel, the charts and the CSV export read), the recorded episodes with their
stills inlined, and the provenance (every invocation that wrote the folder, the versions,
the machine, the world set and where its profiles came from).

Everything here is data from files someone else may have written: numbers are checked as
numbers, text is cut to a bound and stays text (the page autoescapes it or reads it from a
JSON block), and every path is a quoted relative URL inside the folder."""

from __future__ import annotations

import base64
import json
import math
import shlex
import urllib.parse
from collections import Counter
from pathlib import Path

from dynabarn.bench.report_charts import measured
from dynabarn.bench.results import METADATA, WORLDS, invocations_of, recording_path
from dynabarn.bench.row_rules import parse_key
from dynabarn.bench.summary import DIFFICULTIES, FLOOR
from dynabarn.errors import DynabarnError
from dynabarn.metrics import METRICS

STILLS = "report_files"
"""Beside the report: the stills of recorded episodes (PNG), drawn once per recording and
inlined into the page (the folder is a cache; the page needs nothing beside it)."""
OUTCOMES = ("success", "collision", "timeout", "error")
TEXT = 500
"""The longest text a row's field is shown with."""


def world_of(row: dict) -> str:
    """The row's world (a row from a worker that died mid-episode has none: its key's file)."""
    world = row.get("world")
    if isinstance(world, str) and world:
        return world[:TEXT]
    try:
        return Path(parse_key(row["key"])["world"]).stem
    except DynabarnError:
        return "?"


def _number(value) -> float | None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None


def read_worlds(out: Path) -> dict[str, dict]:
    """world name -> its worlds.json entry (empty for folders from before worlds.json)."""
    try:
        return {w["name"]: w for w in json.loads((out / WORLDS).read_text())["worlds"] if isinstance(w, dict)}
    except (OSError, ValueError, KeyError, TypeError, RecursionError):
        return {}


def episode_table(rows: list[dict], worlds: dict[str, dict], planners: list[str]) -> dict:
    """The episodes as columns: indices into `planners`, `worlds` (id, name, difficulty,
    measured difficulty, ordered by id) and `OUTCOMES`; the seed, the reason, every metric
    (`metrics.METRICS`, None where a row has none) and the recording's index (-1: none)."""
    names = sorted({world_of(r) for r in rows})
    first = {}
    for r in rows:
        first.setdefault(world_of(r), r)
    order = {d: i for i, d in enumerate(DIFFICULTIES)}

    def world_id(name: str):
        value = first[name].get("world_id")
        return value if isinstance(value, int) and not isinstance(value, bool) else None

    names.sort(key=lambda n: (world_id(n) if world_id(n) is not None else -1, n))
    world_index = {n: i for i, n in enumerate(names)}
    planner_index = {p: i for i, p in enumerate(planners)}
    metrics = [m.name for m in METRICS]
    columns: dict[str, list] = {k: [] for k in ("planner", "world", "seed", "outcome", "reason", "recording")}
    columns |= {m: [] for m in metrics}
    for r in rows:
        columns["planner"].append(planner_index[r["planner"]])
        columns["world"].append(world_index[world_of(r)])
        seed = r.get("seed")
        columns["seed"].append(seed if isinstance(seed, int) and not isinstance(seed, bool) else -1)
        columns["outcome"].append(OUTCOMES.index(r["outcome"]) if r.get("outcome") in OUTCOMES else 3)
        columns["reason"].append(str(r.get("reason", ""))[:TEXT])
        columns["recording"].append(-1)
        for m in metrics:
            value = _number(r.get(m))
            columns[m].append(None if value is None else round(value, 4))
    return {
        "planners": planners,
        "floor": FLOOR,
        "outcomes": list(OUTCOMES),
        "metrics": [{"name": m.name, "unit": m.unit} for m in METRICS],
        "worlds": [
            {
                "name": n,
                "id": world_id(n),
                "difficulty": str(first[n].get("difficulty", ""))[:40],
                "rank": order.get(first[n].get("difficulty"), len(order)),
                "measured": measured(worlds.get(n)),
            }
            for n in names
        ],
        "episodes": columns,
    }


def recordings(out: Path, rows: list[dict], table: dict) -> tuple[list[dict], str]:
    """The recorded episodes (only files inside the folder: `recording_path`): the file as a
    quoted relative URL, the command that replays it from the report's folder, and its still
    inlined as a data URL (drawn once into `report_files/`, never through a link); the
    table's `recording` column set to each one's index. And a note when no still could be
    drawn there."""
    from dynabarn.bench.stills import still_for

    stills = out / STILLS
    note = ""
    if stills.is_symlink() or (stills.exists() and not stills.is_dir()):
        note = f"{STILLS} is not a folder of this report (a link or a file): no stills were drawn into it"
    found = []
    for i, r in enumerate(rows):
        recording = recording_path(r, out)
        if recording is None:
            continue
        relative = recording.resolve().relative_to(out.resolve()).as_posix()
        still = None if note else still_for(recording, stills)
        table["episodes"]["recording"][i] = len(found)
        found.append(
            {
                "href": "./" + urllib.parse.quote(relative),
                "command": shlex.join(["dynabarn-replay", "--web", relative]),
                "still": "data:image/png;base64," + base64.b64encode(still.read_bytes()).decode("ascii")
                if still
                else None,
            }
        )
    return found, note


def _text(value, limit: int = TEXT) -> str:
    return "" if value is None else str(value)[:limit]


def provenance(out: Path, worlds: dict[str, dict], rows: list[dict]) -> dict:
    """Where the folder's numbers come from: each invocation that wrote it (command line,
    time, versions, machine, planners, episodes; recovered ones say so), the versions and
    machines the rows carry, the world set and its profiles' sources, and how many of its
    worlds are certified solvable."""
    try:
        meta = json.loads((out / METADATA).read_text())
        meta = meta if isinstance(meta, dict) else {}
    except (OSError, ValueError, RecursionError):
        meta = {}
    invocations = []
    for inv in invocations_of(meta)[:200]:
        command = inv.get("command")
        arguments = inv.get("arguments") if isinstance(inv.get("arguments"), dict) else {}
        invocations.append(
            {
                "when": _text(inv.get("when")) or "unknown",
                "command": shlex.join(str(c)[:TEXT] for c in command[:100]) if isinstance(command, list) else "",
                "set": _text(arguments.get("set")),
                "planners": ", ".join(_text(p, 100) for p in (inv.get("planners") or [])[:50]),
                "episodes": _text(inv.get("episodes")),
                "versions": ", ".join(f"{_text(k, 40)} {_text(v, 40)}" for k, v in (inv.get("versions") or {}).items()),
                "machine": ", ".join(f"{_text(k, 40)} {_text(v, 80)}" for k, v in (inv.get("machine") or {}).items()),
                "recovered": _text(inv.get("recovered")),
            }
        )
    versions = Counter(json.dumps(r.get("versions"), sort_keys=True) for r in rows)
    machines = Counter(_text(r["machine"].get("cpu"), 100) for r in rows if isinstance(r.get("machine"), dict))
    profiles = Counter(_text(w.get("profile_set"), 100) or "unknown" for w in worlds.values())
    certified = sum(
        1
        for w in worlds.values()
        if isinstance(w.get("certificates"), dict)
        and any(isinstance(c, dict) and c.get("certified") for c in w["certificates"].values())
    )
    return {
        "invocations": invocations,
        "versions": [f"{n} rows: {_text(v, 300)}" for v, n in versions.most_common(20)],
        "machines": [f"{n} rows: {m or 'unknown'}" for m, n in machines.most_common(20)],
        "worlds": len(worlds),
        "profiles": [f"{n} worlds: {p}" for p, n in profiles.most_common(20)],
        "certified": certified,
        "paper_worlds": sum(1 for w in worlds.values() if w.get("paper") is True),
    }


def json_block(data: object) -> str:
    """`data` as JSON that is safe inside `<script type="application/json">`: no `<`, `>`
    or `&` (escaped), so no text of a row can close the block."""
    text = json.dumps(data, separators=(",", ":"), allow_nan=False, default=str)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
