"""The block of the results pages that sets real move_base beside our DWA.

Imported by `readme_results.py` (which owns the pages and their blocks); nothing here
runs an episode. The folders come from `dynabarn-bench --planner ros --ros-stack
move_base_dwa` and `--planner dwa@dwa_dynabarn_authors` into the same `--out`
(docs/results.md gives the commands).
"""

from __future__ import annotations

from collections import Counter

from dynabarn.bench import DIFFICULTIES
from dynabarn.bench.summary import FLOOR

MOVE_BASE_SETS = {"move_base_paper60": "paper60", "move_base_original60": "release's 60"}
MOVE_BASE_ROWS = (
    ("ros", "real move_base (`--stack move_base_dwa`, lockstep at its 20 Hz)"),
    ("dwa@dwa_dynabarn_authors", "our DWA, the same configuration (`dwa@dwa_dynabarn_authors`)"),
    (FLOOR, "blind floor (`straight`)"),
)


def _cell(s: dict | None) -> str:
    return "-" if s is None else f"{s['success']:.2f} [{s['success_lo']:.2f}, {s['success_hi']:.2f}]"


def _agreement(rows: list[dict]) -> str:
    """How often real move_base and our DWA ended the same (world, trial) the same way."""
    outcome = {(r["planner"], r["world"], r["seed"]): r["outcome"] for r in rows}
    pairs = [(o, outcome.get(("dwa@dwa_dynabarn_authors", w, s))) for (p, w, s), o in outcome.items() if p == "ros"]
    pairs = [(a, b) for a, b in pairs if b is not None]
    if not pairs:
        return "-"
    same = sum(a == b for a, b in pairs)
    kinds = Counter(f"{a} / {b}" for a, b in pairs if a != b)
    differ = ", ".join(f"{k} {n}" for k, n in kinds.most_common())
    return f"{same / len(pairs):.2f} of {len(pairs)} ({differ or 'none differ'})"


def move_base_table(folders: dict[str, tuple[list[dict], list[dict]]]) -> str:
    """Success [95% interval] per difficulty of real move_base, our DWA with its
    configuration and the floor, on each set; then how often the two agree."""
    lines = [
        "| worlds | planner | trials | " + " | ".join(DIFFICULTIES) + " | all | skill over floor, all |",
        "|---|---|---|" + "---|" * (len(DIFFICULTIES) + 2),
    ]
    notes = []
    for folder, title in MOVE_BASE_SETS.items():
        rows, summary = folders.get(folder, ([], []))
        by = {(s["planner"], s["difficulty"]): s for s in summary}
        for planner, name in MOVE_BASE_ROWS:
            if (planner, "all") not in by:
                continue
            trials = len({r["seed"] for r in rows if r["planner"] == planner})
            cells = " | ".join(_cell(by.get((planner, d))) for d in (*DIFFICULTIES, "all"))
            s = by[(planner, "all")]
            skill = "-" if s.get("skill") is None else f"{s['skill']:+.2f} [{s['skill_lo']:+.2f}, {s['skill_hi']:+.2f}]"
            lines.append(f"| {title} | {name} | {trials} | {cells} | {skill} |")
        if rows:
            notes.append(f"- {title}: the same outcome in {_agreement(rows)}.")
    return "\n".join(lines + (["", *notes] if notes else []))
