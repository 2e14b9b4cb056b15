"""The leaderboard page's table (docs/leaderboard.md): every planner on every committed
world set and difficulty, with what it sees, what it trained on, the floor and its skill
over it, and a link to the sweep's report (rendered into the site by docs/hooks.py).

Used by `benchmarks/readme_results.py` (block `leaderboard`); nothing here runs an episode.
"""

from __future__ import annotations

from dynabarn.bench.stats import skill_text
from dynabarn.bench.summary import DIFFICULTIES, FLOOR

REPORTS = "reports"
"""The site's folder of the sweeps' reports, one `FOLDER.html` each (docs/hooks.py)."""

SEES = {
    FLOOR: "nothing (blind)",
    "dwa": "laser",
    "teb": "laser",
    "dwa@dwa_dynamic": "laser + tracker",
    "teb@teb_dynamic": "laser + tracker",
    "dwa@dwa_dynabarn_authors": "laser",
    "teb@teb_ros_defaults": "laser",
    "predictive": "laser + tracker",
    "bc": "laser (learned)",
    "td3": "laser (learned)",
    "dagger": "laser + tracker (learned)",
    "oracle_present": "**privileged**: true present state",
    "oracle": "**privileged**: the exact future",
    "ros": "laser (move_base)",
}
"""What each planner's decisions read (docs/concepts/baselines.md, perception.md)."""

TRAINED_ON = {
    "bc": "oracle demonstrations on all 300 generated worlds",
    "td3": "`paper60`'s worlds (as the paper)",
    "dagger": "procedural worlds of its own seed namespace only (the paper's and the tiers' profiles)",
}
"""Where a learned planner's weights come from (docs/tutorials/training.md); the others are not trained."""


def _cell(s: dict | None) -> str:
    if s is None:
        return "-"
    return f"{s['success']:.2f} [{s['success_lo']:.2f}, {s['success_hi']:.2f}]"


def _skill(s: dict | None) -> str:
    if s is None or s.get("skill") is None:
        return "-"
    return skill_text(s)


def leaderboard_table(folders: dict[str, tuple[list[dict], list[dict]]], names: dict[str, str]) -> str:
    """One row per (world set, planner): success per difficulty with 95% Wilson intervals, the
    floor's and the skill over it on all difficulties (95% interval clustered by world), in
    order of success on all difficulties within each set."""
    head = (
        "| world set | planner | sees | trained on | episodes | easy | medium | hard | floor, same episodes (all) "
        "| skill over floor (all) | report |"
    )
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for folder, label in names.items():
        _, summary = folders.get(folder, ([], []))
        by = {(s["planner"], s["difficulty"]): s for s in summary}
        planners = sorted({p for p, _ in by}, key=lambda p: (p == FLOOR, -by[(p, "all")]["success"], p))
        for planner in planners:
            everything = by[(planner, "all")]
            floor = everything.get("floor")  # on the planner's own (world, seed) pairs
            cells = [_cell(by.get((planner, d))) for d in DIFFICULTIES]
            base = planner.split("@")[0]
            floor_text = f"{floor:.2f}" if floor is not None else "-"
            lines.append(
                f"| {label} | `{planner}` | {SEES.get(planner, SEES.get(base, '?'))} | {TRAINED_ON.get(base, '-')} "
                f"| {everything['episodes']} | " + " | ".join(cells) + f" | {floor_text} "
                f"| {_skill(everything) if planner != FLOOR else '-'} "
                f'| <a href="{REPORTS}/{folder}.html">report</a> |'
            )
    return "\n".join(lines)


def tier_ladder_table(folders: dict[str, tuple[list[dict], list[dict]]], tiers: dict[str, str], ladder) -> str:
    """Each rung of `ladder` ((planner, sees, what), ...) on the hard worlds of every tier,
    with its 95% interval: the scale beyond the paper's hard, where the rungs part."""
    present = [folder for folder in tiers if folders.get(folder, ([], []))[1]]
    names = [tiers[f].split(":")[0] for f in present]
    lines = [
        "| rung | sees | " + " | ".join(f"{n}, hard" for n in names) + " |",
        "|---|---|" + "---|" * len(present),
    ]
    by = {f: {(s["planner"], s["difficulty"]): s for s in folders[f][1]} for f in present}
    for planner, sees, what in ladder:
        if not any((planner, "hard") in by[f] for f in present):
            continue
        cells = [_cell(by[f].get((planner, "hard"))) for f in present]
        lines.append(f"| {what} (`{planner}`) | {sees} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
