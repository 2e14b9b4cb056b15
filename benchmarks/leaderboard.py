"""The leaderboard page's table (docs/leaderboard.md): every planner on every committed
world set and difficulty, with what it sees, what it trained on, the floor and its skill
over it, and a link to the sweep's report (rendered into the site by docs/hooks.py).

Used by `benchmarks/readme_results.py` (block `leaderboard`); nothing here runs an episode.
"""

from __future__ import annotations

import html
import re

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
    "teb@teb_dynamic_uncertain": "laser + tracker",
    "dwa@dwa_dynabarn_authors": "laser",
    "teb@teb_ros_defaults": "laser",
    "predictive": "laser + tracker",
    "bc": "laser (learned)",
    "td3": "laser (learned)",
    "dagger": "laser + tracker (learned)",
    "oracle_present": "**privileged**: true present state",
    "oracle": "**privileged**: the exact future",
    "ros --stack move_base_dwa": "laser (real move_base, ROS 1)",
    "ros --stack nav2_dwb": "laser (real Nav2 DWB, ROS 2)",
    "ros --stack nav2_mppi": "laser (real Nav2 MPPI, ROS 2)",
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


def _html(text: str) -> str:
    """Markdown's `code` and **bold** of the fixed texts above, as HTML (the table is HTML:
    sortable, a sticky planner column)."""
    text = html.escape(text, quote=False)
    text = re.sub(r"`([^`]+)`", r"<code>\1</code>", text)
    return re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", text)


def _td(text: str, sort: float | str | None = None, cls: str = "") -> str:
    """A cell; `sort` the value the page's sort reads (the text where there is none)."""
    shown = round(sort, 4) if isinstance(sort, float) else sort
    attributes = "" if sort is None else f' data-sort="{html.escape(str(shown))}"'
    attributes += f' class="{cls}"' if cls else ""
    return f"<td{attributes}>{text}</td>"


COLUMNS = (
    "planner",
    "sees",
    "trained on",
    "episodes",
    "success (all)",
    "BARN score (all)",
    *DIFFICULTIES,
    "floor, same episodes (all)",
    "skill over floor (all)",
    "report",
)


def leaderboard_table(
    folders: dict[str, tuple[list[dict], list[dict]]],
    names: dict[str, str],
    guests: dict[str, tuple[tuple[str, str, str], ...]] | None = None,
) -> str:
    """A section per world set: one row per planner, success on all difficulties beside the
    BARN score, success per difficulty with 95% Wilson intervals, the floor's success and the
    skill over it; in order of success on all difficulties, sortable by any column (the
    site's `leaderboard.js`), the planner column kept in view. `guests[folder]` adds rows
    swept into folders of their own: (their folder, the planner in its rows, the name shown),
    each linking its own folder's report."""
    parts = []
    for folder, label in names.items():
        _, summary = folders.get(folder, ([], []))
        if not summary:
            continue
        by = {(s["planner"], s["difficulty"]): s for s in summary}
        report_of = dict.fromkeys((p for p, _ in by), folder)
        for guest_folder, planner, shown in (guests or {}).get(folder, ()):
            for s in folders.get(guest_folder, ([], []))[1]:
                if s["planner"] == planner:
                    by[(shown, s["difficulty"])] = {**s, "planner": shown}
                    report_of[shown] = guest_folder
        planners = sorted({p for p, _ in by}, key=lambda p: (p == FLOOR, -by[(p, "all")]["success"], p))
        head = "".join(f"<th>{html.escape(c)}</th>" for c in COLUMNS)
        rows = []
        for planner in planners:
            everything = by[(planner, "all")]
            floor = everything.get("floor")  # on the planner's own (world, seed) pairs
            base = planner.split("@")[0]
            cells = [
                _td(f"<code>{html.escape(planner)}</code>", planner, "planner"),
                _td(_html(SEES.get(planner, SEES.get(base, "?")))),
                _td(_html(TRAINED_ON.get(base, "-"))),
                _td(str(everything["episodes"]), everything["episodes"]),
                _td(_cell(everything), everything["success"]),
                _td(f"{everything['score']:.3f}", everything["score"]),
                *(
                    _td(_cell(by.get((planner, d))), by[(planner, d)]["success"] if (planner, d) in by else -1)
                    for d in DIFFICULTIES
                ),
                _td(f"{floor:.2f}" if floor is not None else "-", floor if floor is not None else -1),
                _td(
                    html.escape(_skill(everything)) if planner != FLOOR else "-",
                    everything["skill"] if everything.get("skill") is not None else -9,
                ),
                _td(f'<a href="{REPORTS}/{report_of[planner]}.html">report</a>'),
            ]
            rows.append("<tr>" + "".join(cells) + "</tr>")
        parts += [
            f"### {label}",
            "",
            '<div class="leaderboard-scroll"><table class="leaderboard sortable">',
            f"<thead><tr>{head}</tr></thead>",
            "<tbody>",
            *rows,
            "</tbody></table></div>",
            "",
        ]
    return "\n".join(parts).rstrip()


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
