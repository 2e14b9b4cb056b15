"""The block of the results pages that sets real move_base beside our DWA.

Imported by `readme_results.py` (which owns the pages and their blocks); nothing here
runs an episode. The folders come from `dynabarn-bench --planner ros --ros-stack
move_base_dwa` and `--planner dwa@dwa_dynabarn_authors` into the same `--out`
(docs/results.md gives the commands).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

from dwa_ablation import VARIANTS, read_outcomes

from dynabarn.bench import DIFFICULTIES
from dynabarn.bench.stats import skill_text
from dynabarn.bench.summary import FLOOR, wilson_interval


@dataclass(frozen=True)
class Comparison:
    """A results folder where a real ROS stack and our planner with its configuration ran the
    same worlds and trials, with the floor."""

    folder: str
    title: str
    real: str  # how the real stack's rows (planner "ros") are named
    ours: tuple[tuple[str, str], ...]  # our planners: (name in the rows, how the table names it)


DWA_OURS = (
    ("dwa@dwa_dynabarn_authors", "our DWA, the same configuration (`dwa@dwa_dynabarn_authors`)"),
    (
        "trajectory_planner@dwa_dynabarn_authors",
        "our TrajectoryPlanner, the same (`trajectory_planner@dwa_dynabarn_authors`)",
    ),
)
COMPARISONS = (
    Comparison(
        "move_base_paper60",
        "paper60",
        "real move_base (`--stack move_base_dwa`, lockstep at its 20 Hz)",
        DWA_OURS,
    ),
    Comparison(
        "move_base_original60",
        "release's 60",
        "real move_base (`--stack move_base_dwa`, lockstep at its 20 Hz)",
        DWA_OURS,
    ),
    Comparison(
        "move_base_teb_paper60",
        "paper60",
        "real TEB under move_base (`--stack move_base_teb`, its ROS defaults)",
        (("teb@teb_ros_defaults", "our TEB, ROS's defaults (`teb@teb_ros_defaults`)"),),
    ),
    Comparison(
        "move_base_teb_original60",
        "release's 60",
        "real TEB under move_base (`--stack move_base_teb`, its ROS defaults)",
        (("teb@teb_ros_defaults", "our TEB, ROS's defaults (`teb@teb_ros_defaults`)"),),
    ),
)
MOVE_BASE_SETS = {c.folder: c.title for c in COMPARISONS}


def _cell(s: dict | None) -> str:
    return "-" if s is None else f"{s['success']:.2f} [{s['success_lo']:.2f}, {s['success_hi']:.2f}]"


def _agreement(rows: list[dict], ours: str) -> str:
    """How often the real stack and our planner ended the same (world, trial) the same way."""
    pairs = _pairs([r for r in rows if r["planner"] == "ros"], [r for r in rows if r["planner"] == ours])
    if not pairs:
        return "-"
    same = sum(a == b for a, b in pairs)
    kinds = Counter(f"{a} / {b}" for a, b in pairs if a != b)
    differ = ", ".join(f"{k} {n}" for k, n in kinds.most_common())
    return f"{same / len(pairs):.2f} of {len(pairs)} ({differ or 'none differ'})"


def move_base_table(folders: dict[str, tuple[list[dict], list[dict]]]) -> str:
    """Success [95% interval] per difficulty of each real stack, our planner with its
    configuration and the floor, on each set; then how often the two agree."""
    lines = [
        "| worlds | planner | trials | " + " | ".join(DIFFICULTIES) + " | all | skill over floor, all |",
        "|---|---|---|" + "---|" * (len(DIFFICULTIES) + 2),
    ]
    notes = []
    for c in COMPARISONS:
        rows, summary = folders.get(c.folder, ([], []))
        by = {(s["planner"], s["difficulty"]): s for s in summary}
        for planner, name in (("ros", c.real), *c.ours, (FLOOR, "blind floor (`straight`)")):
            if (planner, "all") not in by:
                continue
            trials = len({r["seed"] for r in rows if r["planner"] == planner})
            cells = " | ".join(_cell(by.get((planner, d))) for d in (*DIFFICULTIES, "all"))
            s = by[(planner, "all")]
            skill = skill_text(s)
            lines.append(f"| {c.title} | {name} | {trials} | {cells} | {skill} |")
        for ours, _ in c.ours if rows else ():
            if any(r["planner"] == ours for r in rows):
                notes.append(f"- {c.title}, `{ours.split('@')[0]}`: the same outcome in {_agreement(rows, ours)}.")
    return "\n".join(lines + (["", *notes] if notes else []))


def ablation_table(folders: dict[str, tuple[list[dict], list[dict]]]) -> str:
    """Each variant of `dwa_ablation.py` beside real move_base on paper60: success per
    difficulty, and how often it ends a (world, trial) as the real stack did."""
    real_rows = [r for r in folders.get("move_base_paper60", ([], []))[0] if r["planner"] == "ros"]
    real = {(r["world"], r["seed"]): r["outcome"] for r in real_rows}
    by_variant: dict[str, list[dict]] = {}
    for row in read_outcomes():
        by_variant.setdefault(row["variant"], []).append(row)
    lines = [
        "| variant | episodes | " + " | ".join(DIFFICULTIES) + " | all | same outcome as real move_base "
        "| real succeeds, it does not | it succeeds, real does not |",
        "|---|---|" + "---|" * (len(DIFFICULTIES) + 4),
    ]
    for name, rows in (("real", real_rows), *by_variant.items()):
        title = "real move_base (`results/move_base_paper60`)" if name == "real" else VARIANTS[name][2]
        cells = []
        for d in (*DIFFICULTIES, "all"):
            group = [r for r in rows if d == "all" or r["difficulty"] == d]
            if not group:
                cells.append("-")
                continue
            k = sum(r["outcome"] == "success" for r in group)
            lo, hi = wilson_interval(k, len(group))
            cells.append(f"{k / len(group):.2f}" + (f" [{lo:.2f}, {hi:.2f}]" if d == "all" else ""))
        paired = [(real[(r["world"], r["seed"])], r["outcome"]) for r in rows if (r["world"], r["seed"]) in real]
        if name == "real" or not paired:
            agree = ["-", "-", "-"]
        else:
            same = sum(a == b for a, b in paired)
            lo, hi = wilson_interval(same, len(paired))
            agree = [
                f"{same / len(paired):.2f} [{lo:.2f}, {hi:.2f}] of {len(paired)}",
                str(sum(a == "success" != b for a, b in paired)),
                str(sum(b == "success" != a for a, b in paired)),
            ]
        lines.append(f"| {title} | {len(rows)} | " + " | ".join(cells + agree) + " |")
    return "\n".join(lines)


@dataclass(frozen=True)
class StackRow:
    """One row of the ROS stacks' table: a planner's rows in a results folder."""

    folder: str
    planner: str  # its name in the rows ("ros" for a real stack)
    title: str
    stack: str | None = None  # a real stack's name (`--stack`)


def _set_rows(set_folder: str, name: str) -> tuple[StackRow, ...]:
    """The table's rows for one world set: each real stack from its own sweep (`stack_folder`),
    our planners and the floor from the set's own folder."""
    real = (
        ("nav2_dwb", "real Nav2 DWB (`--stack nav2_dwb`, ROS 2)"),
        ("nav2_mppi", "real Nav2 MPPI (`--stack nav2_mppi`, ROS 2)"),
        ("move_base_dwa", "real move_base DWA (`--stack move_base_dwa`, ROS 1)"),
    )
    return (
        *(StackRow(stack_folder(stack, name), "ros", title, stack) for stack, title in real),
        StackRow(set_folder, "dwa", "our DWA (`dwa`)"),
        StackRow(set_folder, "predictive", "our predictive planner (`predictive`)"),
        StackRow(set_folder, FLOOR, "blind floor (`straight`)"),
    )


def stack_folder(stack: str, name: str) -> str:
    """Where a real stack's sweep of world set `name` is: results/STACK_NAME (move_base's,
    swept first, as results/move_base_NAME)."""
    return f"move_base_{name}" if stack == "move_base_dwa" else f"{stack}_{name}"


NAV2_SETS = {
    "paper60": _set_rows("paper60_barn", "paper60"),
    "release's 60": _set_rows("original60_barn", "original60"),
}
"""The ROS stacks' table: per world set, Nav2 and move_base (real, in lockstep) beside ours."""
NAV2_FOLDERS = tuple(
    r.folder for rows in NAV2_SETS.values() for r in rows if r.stack and r.folder not in MOVE_BASE_SETS
)
STACK_GUESTS = {
    next(r.folder for r in rows if r.stack is None): tuple(
        (r.folder, r.planner, f"ros --stack {r.stack}") for r in rows if r.stack
    )
    for rows in NAV2_SETS.values()
}
"""The real stacks listed in their world set's section of the leaderboard (`leaderboard_table`'s
guests): {the set's folder: (the stack's folder, its rows' planner, the name shown)}."""


def _pairs(real: list[dict], ours: list[dict]) -> list[tuple[str, str]]:
    """(real's outcome, ours) on each (world, trial) both ran, in the order of `real`."""
    mine = {(r["world"], r["seed"]): r["outcome"] for r in ours}
    return [(r["outcome"], mine[(r["world"], r["seed"])]) for r in real if (r["world"], r["seed"]) in mine]


def _same_episodes(real: list[dict], ours: list[dict]) -> str:
    """Success of `ours` on exactly the (world, trial) pairs `real` ran, and how often the
    two ended them the same way."""
    pairs = _pairs(real, ours)
    if not pairs:
        return "-"
    same = sum(a == b for a, b in pairs)
    return f"{sum(b == 'success' for _, b in pairs) / len(pairs):.2f} ({same} of {len(pairs)} the same)"


def nav2_table(folders: dict[str, tuple[list[dict], list[dict]]]) -> str:
    """Success [95% interval] per difficulty of real Nav2 (DWB, MPPI) and move_base beside
    our DWA, our predictive planner and the floor, on each set; each with its trials, the
    skill over the floor on its own episodes, and, for our planners, their success on the
    episodes Nav2 DWB ran."""
    lines = [
        "| worlds | planner | trials | " + " | ".join(DIFFICULTIES) + " | all | skill over floor, all "
        "| on Nav2 DWB's episodes |",
        "|---|---|---|" + "---|" * (len(DIFFICULTIES) + 3),
    ]
    for title, rows_of in NAV2_SETS.items():
        dwb_rows = [r for r in folders.get(rows_of[0].folder, ([], []))[0] if r["planner"] == "ros"]
        for row in rows_of:
            rows, summary = folders.get(row.folder, ([], []))
            by = {(s["planner"], s["difficulty"]): s for s in summary}
            if (row.planner, "all") not in by:
                continue
            mine = [r for r in rows if r["planner"] == row.planner]
            trials = len({r["seed"] for r in mine})
            cells = " | ".join(_cell(by.get((row.planner, d))) for d in (*DIFFICULTIES, "all"))
            paired = "-" if row is rows_of[0] else _same_episodes(dwb_rows, mine)
            lines.append(f"| {title} | {row.title} | {trials} | {cells} | {skill_text(by[(row.planner, 'all')])} "
                         f"| {paired} |")  # fmt: skip
    return "\n".join(lines)
