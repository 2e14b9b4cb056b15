"""`report.html`: one self-contained page per results folder, to look into a sweep.

The page is rendered by Jinja2 from the package's template (`report_assets/`), with its
style, script and figures inlined (SVG from matplotlib) and the data it sorts embedded as
JSON: it opens from disk with no network, and its Content-Security-Policy lets nothing
load from elsewhere. It shows the summary with intervals and the skill over the floor; per
planner, a grid of worlds x trials coloured by outcome (each cell's time, clearance and
reason on hover; sortable by world, difficulty, measured difficulty and successes);
success against measured difficulty; the tracking quality of planners with a tracker; for
every recorded episode, a still of its last moment (`report_files/`, drawn from the MCAP
file) and the command that replays it; and the last `--verify` of the folder.

Written at the end of every sweep (a resumed one rewrites it with every row so far) and by
`dynabarn-bench --report DIR` for any folder, older ones included.
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import math
import shlex
import urllib.parse
from collections import defaultdict
from importlib import resources
from pathlib import Path

from dynabarn.bench.results import (
    METADATA,
    RESULTS,
    WORLDS,
    certified_episodes,
    paper_worlds,
    read_results,
    recording_path,
)
from dynabarn.bench.row_rules import parse_key
from dynabarn.bench.summary import DIFFICULTIES, FLOOR, summarise, wilson_interval
from dynabarn.bench.verify import VERIFICATION
from dynabarn.errors import DynabarnError
from dynabarn.files import write_atomically

REPORT = "report.html"
STILLS = "report_files"
"""Beside the report: the stills of recorded episodes (PNG), drawn once per recording."""
OUTCOME_COLOURS = {"success": "#2e7d32", "collision": "#c62828", "timeout": "#f9a825", "error": "#6a1b9a"}
MEASURED = "corridor_blocked"
"""The measured difficulty the grid sorts by and the figure's axis (`worlds.difficulty`):
the share of time the straight corridor to the goal is blocked."""
DIFFICULTY_BINS = 5


def write_report(out_dir: Path) -> Path:
    """Render `OUT/report.html` from the folder's rows (atomically); returns its path."""
    out = Path(out_dir)
    if not (out / RESULTS).is_file():
        raise DynabarnError(f"{out}: no {RESULTS} (not a results folder of dynabarn-bench)")
    rows = read_results(out / RESULTS)
    if not rows:
        raise DynabarnError(f"{out / RESULTS}: no results rows yet")
    html = render_report(out, rows)
    path = out / REPORT
    try:
        # A row's text may hold a lone surrogate (JSON allows "\ud800"): shown as U+FFFD.
        write_atomically(path, html.encode("utf-8", "replace"))
    except OSError as exc:
        raise DynabarnError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


def csp_hash(text: str) -> str:
    """A Content-Security-Policy source admitting exactly the inline `text` (CSP level 2)."""
    return "sha256-" + base64.b64encode(hashlib.sha256(text.encode("utf-8")).digest()).decode("ascii")


def render_report(out: Path, rows: list[dict]) -> str:
    """The page's HTML for the folder `out` and its rows. Everything from the rows or the
    folder's files is text to the page: autoescaped, every URL a quoted relative path inside
    the folder, every command quoted for the shell; the page's own script and style run by
    their hashes and nothing else does."""
    import jinja2

    worlds = _worlds(out)
    summary = summarise(rows, paper_worlds(out), certified_episodes(out))
    planners = sorted({r["planner"] for r in rows}, key=lambda p: (p != FLOOR, p))
    assets = resources.files("dynabarn.bench") / "report_assets"
    script = (assets / "report.js").read_text(encoding="utf-8")
    style = (assets / "report.css").read_text(encoding="utf-8")
    env = jinja2.Environment(
        loader=jinja2.FunctionLoader(lambda name: (assets / name).read_text(encoding="utf-8")),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
    )
    template = env.get_template("report.html.j2")
    recordings, stills_note = _recordings(out, rows)
    return template.render(
        title=_title(out),
        summary=summary,
        difficulties=(*DIFFICULTIES, "all"),
        planners=planners,
        grid=grid_data(rows, worlds),
        colours=OUTCOME_COLOURS,
        figure=difficulty_figure(rows, worlds),
        tracking=[s for s in summary if s.get("track_recall") is not None],
        recordings=recordings,
        stills_note=stills_note,
        verification=_verification(out),
        n_rows=len(rows),
        script=script,
        script_hash=csp_hash(script),
        style=style,
        style_hash=csp_hash(style),
    )


def _title(out: Path) -> str:
    try:
        meta = json.loads((out / METADATA).read_text())
        args = meta.get("arguments", {})
        return f"{out.name}: set {args.get('set', '?')}, protocol {args.get('protocol', '?')}"
    except (OSError, ValueError, AttributeError, TypeError):
        return out.name


def _worlds(out: Path) -> dict[str, dict]:
    """world name -> its worlds.json entry (empty for folders from before worlds.json)."""
    try:
        return {w["name"]: w for w in json.loads((out / WORLDS).read_text())["worlds"]}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def _measured(world: dict | None) -> float | None:
    value = ((world or {}).get("measured") or {}).get(MEASURED)
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else None


def _world_of(row: dict) -> str:
    """The row's world (a row from a worker that died mid-episode has none: its key's file)."""
    world = row.get("world")
    if world:
        return world
    try:
        return Path(parse_key(row["key"])["world"]).stem
    except DynabarnError:
        return "?"


def grid_data(rows: list[dict], worlds: dict[str, dict]) -> dict[str, dict]:
    """Per planner: its seeds and one row per world, each with its trials' cells (outcome,
    time, clearance, reason; None where the trial has not run)."""
    out: dict[str, dict] = {}
    by_planner: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        by_planner[r["planner"]].append(r)
    order = {d: i for i, d in enumerate(DIFFICULTIES)}
    for planner, rs in by_planner.items():
        seeds = sorted({r["seed"] for r in rs})
        cells: dict[str, dict[int, dict]] = defaultdict(dict)
        first: dict[str, dict] = {}  # each world's first row: its id and difficulty
        for r in rs:
            name = _world_of(r)
            first.setdefault(name, r)
            cells[name][r["seed"]] = {
                "outcome": r["outcome"],
                "time": r.get("time"),
                "clearance": r.get("min_clearance"),
                "reason": r.get("reason", ""),
            }
        world_rows = []
        for name, trials in cells.items():
            sample = first[name]
            world_id = sample.get("world_id")
            world_rows.append(
                {
                    "world": name,
                    # A whole number or nothing (a row of mixed text and numbers must still sort).
                    "id": world_id if isinstance(world_id, int) and not isinstance(world_id, bool) else None,
                    "difficulty": sample.get("difficulty", ""),
                    "difficulty_rank": order.get(sample.get("difficulty"), len(order)),
                    "measured": _measured(worlds.get(name)),
                    "successes": sum(c["outcome"] == "success" for c in trials.values()),
                    "cells": [trials.get(s) for s in seeds],
                }
            )
        world_rows.sort(key=lambda w: (w["id"] if w["id"] is not None else -1, w["world"]))
        out[planner] = {"seeds": seeds, "worlds": world_rows}
    return out


def difficulty_figure(rows: list[dict], worlds: dict[str, dict]) -> str | None:
    """Success against measured difficulty (worlds in quantile bins of it), per planner,
    with 95% Wilson intervals: an SVG as a data URL (None when no world has a measured difficulty)."""
    measured = {name: _measured(w) for name, w in worlds.items()}
    values = sorted(v for v in measured.values() if v is not None)
    if len(values) < DIFFICULTY_BINS:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    edges = np.quantile(values, np.linspace(0, 1, DIFFICULTY_BINS + 1))
    centres = 0.5 * (edges[:-1] + edges[1:])
    fig, ax = plt.subplots(figsize=(7.5, 4.0), dpi=100)
    for planner in sorted({r["planner"] for r in rows}):
        hits, totals = np.zeros(DIFFICULTY_BINS), np.zeros(DIFFICULTY_BINS)
        for r in rows:
            m = measured.get(r.get("world"))
            if r["planner"] == planner and m is not None:
                b = min(int(np.searchsorted(edges, m, side="right")) - 1, DIFFICULTY_BINS - 1)
                hits[max(b, 0)] += r["outcome"] == "success"
                totals[max(b, 0)] += 1
        ok = totals > 0
        rate = np.divide(hits, totals, out=np.zeros_like(hits), where=ok)
        pairs = zip(hits, totals, strict=True)
        lo_hi = np.array([wilson_interval(int(k), int(n)) if n else (0.0, 0.0) for k, n in pairs])
        err = np.abs(lo_hi.T - rate)
        style = {"linestyle": "--", "color": "0.4"} if planner == FLOOR else {}
        ax.errorbar(centres[ok], rate[ok], yerr=err[:, ok], marker="o", capsize=3, label=planner, **style)
    ax.set_xlabel("corridor blocked (measured difficulty; bins of equal world counts)")
    ax.set_ylabel("success")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    buffer = io.StringIO()
    fig.savefig(buffer, format="svg", metadata={"Date": None})
    plt.close(fig)
    # An image, not inline SVG: matplotlib's style attributes stay inside the picture, where
    # the page's policy, which admits no inline style, does not reach.
    return "data:image/svg+xml;base64," + base64.b64encode(buffer.getvalue().encode("utf-8")).decode("ascii")


def _recordings(out: Path, rows: list[dict]) -> tuple[list[dict], str]:
    """Recorded episodes (only files inside the folder: `recording_path`): their still
    (drawn once, `stills.draw_still`, only into a real `report_files/` folder, never through
    a link), the file as a quoted relative URL and the command that replays it, quoted for
    the shell; and a note when no still could be drawn there."""
    from dynabarn.bench.stills import still_for

    stills = out / STILLS
    note = ""
    if stills.is_symlink() or (stills.exists() and not stills.is_dir()):
        note = f"{STILLS} is not a folder of this report (a link or a file): no stills were drawn into it"
    found = []
    for r in rows:
        recording = recording_path(r, out)
        if recording is None:
            continue
        relative = recording.resolve().relative_to(out.resolve()).as_posix()
        still = None if note else still_for(recording, stills)
        found.append(
            {
                "planner": r["planner"],
                "world": _world_of(r),
                "seed": r["seed"],
                "outcome": r["outcome"],
                "reason": r.get("reason", ""),
                "href": "./" + urllib.parse.quote(relative),
                "still": "./" + urllib.parse.quote(f"{STILLS}/{still.name}") if still else None,
                "command": shlex.join(["dynabarn-replay", "--web", str(out / relative)]),
            }
        )
    return found, note


VERIFICATION_FIELDS = {"when": str, "checked": int, "identical": int, "ok": bool, "differences": list, "notes": list}
"""What the report shows of `verification.json`, with each field's type."""


def _verification(out: Path, *, site: bool = False) -> dict | None:
    """The folder's last verdict, as plain text fields; `damaged` says why when the file is
    there but not a verdict of `--verify` (the report shows that, never a template error).
    For the documentation site (`site`), only a complete verdict: every sampled row checked
    by an install with every extra (a local one that skipped rows says nothing of them)."""
    path = out / VERIFICATION
    if not path.is_file():
        return None
    if site:
        try:
            complete = json.loads(path.read_text(encoding="utf-8", errors="replace")).get("complete") is True
        except (OSError, ValueError, RecursionError, AttributeError):
            complete = False
        if not complete:
            return None
    try:
        data = json.loads(path.read_text(encoding="utf-8", errors="replace"))
    except (OSError, ValueError, RecursionError) as exc:
        return {"damaged": f"not JSON: {type(exc).__name__}"}
    if not isinstance(data, dict):
        return {"damaged": "not a JSON object"}
    for name, kind in VERIFICATION_FIELDS.items():
        value = data.get(name)
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            return {"damaged": f"{name} is not a {kind.__name__}"}
    differences = [
        {k: str(d.get(k, ""))[:500] for k in ("key", "field", "old", "new")}
        for d in data["differences"][:1000]
        if isinstance(d, dict)
    ]
    notes = [str(n)[:500] for n in data["notes"][:100]]
    return {"damaged": "", **{k: data[k] for k in ("when", "checked", "identical", "ok")}} | {
        "differences": differences,
        "notes": notes,
    }
