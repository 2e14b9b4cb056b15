"""`dynabarn-bench --compare A B`: two planners side by side on the episodes both ran.

A and B are results folders; each side is one planner of its folder (`--planner X,Y` names
them; a folder of one planner besides the floor needs no naming). Two episodes pair when they
ran the same world file (name and sha256), protocol, seed and simulation settings, so two
sweeps of the same worlds compare whoever ran them. Per difficulty and over all: the paired
difference of success (A minus B) with the skill's interval (`stats.paired_difference_interval`:
never outside [-1, 1], never of zero width), and the worlds where they disagree (a world
where one succeeded more often than the other). Printed, and written as a report whose
grid holds the two side by side (`--out DIR`: DIR/report.html, DIR/comparison.json)."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

from dynabarn.bench.results import RESULTS, is_row, read_results
from dynabarn.bench.row_rules import parse_key
from dynabarn.bench.stats import FEW_WORLDS_NOTE, MIN_WORLDS, difference_text, paired_difference_interval
from dynabarn.bench.summary import DIFFICULTIES, FLOOR
from dynabarn.errors import DynabarnError


def _episode(row: dict) -> tuple:
    """What makes two rows the same episode, whoever ran them."""
    parts = parse_key(row["key"])
    return (parts["world"], row.get("world_sha256"), parts["protocol"], parts["seed"], json.dumps(parts["sim"]))


def side(folder: Path, planner: str | None) -> tuple[str, list[dict]]:
    """One side of a comparison: (planner, its rows) from `folder`; without `planner`, the
    folder's only planner besides the floor (one line naming them when there are more)."""
    file = Path(folder) / RESULTS
    if not file.is_file():
        raise DynabarnError(f"{folder}: no {RESULTS} (not a results folder of dynabarn-bench)")
    rows = [r for r in read_results(file) if is_row(r) and not r.get("retry")]
    planners = sorted({r["planner"] for r in rows})
    if planner is None:
        candidates = [p for p in planners if p != FLOOR] or planners
        if len(candidates) != 1:
            raise DynabarnError(
                f"{folder} holds {len(candidates)} planners ({', '.join(candidates)}): name the two to compare "
                "with --planner A_PLANNER,B_PLANNER"
            )
        planner = candidates[0]
    if planner not in planners:
        raise DynabarnError(f"{folder}: no rows of planner {planner!r}; it holds {', '.join(planners)}")
    return planner, [r for r in rows if r["planner"] == planner]


def compare(a_rows: list[dict], b_rows: list[dict]) -> dict:
    """The paired comparison of two planners' rows on their shared episodes."""
    b_by_episode = {_episode(r): r for r in b_rows}
    pairs = []  # (the episode's world file, A's success, B's success), each key parsed once
    groups: dict[str, list] = defaultdict(list)
    for a in a_rows:
        episode = _episode(a)
        b = b_by_episode.get(episode)
        if b is not None:
            pair = (episode[0], a["outcome"] == "success", b["outcome"] == "success")
            pairs.append(pair)
            groups[a.get("difficulty", "?")].append(pair)
            groups["all"].append(pair)
    order = {d: i for i, d in enumerate((*DIFFICULTIES, "all"))}
    out = []
    for difficulty in sorted(groups, key=lambda d: order.get(d, len(order))):
        by_world: dict[str, list[tuple[bool, bool]]] = defaultdict(list)
        for world, a_won, b_won in groups[difficulty]:
            by_world[world].append((a_won, b_won))
        estimate, lo, hi = paired_difference_interval([[float(x) - float(y) for x, y in v] for v in by_world.values()])
        n = len(groups[difficulty])
        out.append(
            {
                "difficulty": difficulty,
                "episodes": n,
                "worlds": len(by_world),
                "success_a": sum(x for v in by_world.values() for x, _ in v) / n,
                "success_b": sum(y for v in by_world.values() for _, y in v) / n,
                "difference": estimate,
                "lo": lo,
                "hi": hi,
                "text": difference_text(estimate, lo, hi, len(by_world)),
                "disagree": sorted(
                    (
                        {"world": Path(w).stem, "a": sum(x for x, _ in v), "b": sum(y for _, y in v), "trials": len(v)}
                        for w, v in by_world.items()
                        if sum(x for x, _ in v) != sum(y for _, y in v)
                    ),
                    key=lambda d: (-abs(d["a"] - d["b"]), d["world"]),
                ),
            }
        )
    return {"shared": len(pairs), "a_only": len(a_rows) - len(pairs), "b_only": len(b_rows) - len(pairs), "rows": out}


def format_comparison(result: dict, a: str, b: str) -> str:
    lines = [
        f"A = {a}, B = {b}: {result['shared']} shared episodes"
        + (
            f" ({result['a_only']} only in A, {result['b_only']} only in B, left out)"
            if result["a_only"] or result["b_only"]
            else ""
        ),
        f"{'difficulty':<11}{'episodes':>9}{'worlds':>8}{'A':>7}{'B':>7}  {'A - B [95% CI]':<24}"
        "worlds that disagree (A/B successes)",
    ]
    for r in result["rows"]:
        shown = ", ".join(f"{d['world']} {d['a']}/{d['b']}" for d in r["disagree"][:6])
        more = f" and {len(r['disagree']) - 6} more" if len(r["disagree"]) > 6 else ""
        lines.append(
            f"{r['difficulty']:<11}{r['episodes']:>9}{r['worlds']:>8}{r['success_a']:>7.2f}{r['success_b']:>7.2f}  "
            f"{r['text']:<24}{len(r['disagree'])}: {shown or '-'}{more}"
        )
    if any(r["worlds"] < MIN_WORLDS for r in result["rows"]):
        lines.append(FEW_WORLDS_NOTE)
    return "\n".join(lines)
