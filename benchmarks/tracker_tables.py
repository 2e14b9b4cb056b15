"""The laser trackers' table (issue 57), from the committed sweeps of
`benchmarks/tracker_sweeps.py`: per world set's hard worlds, the circle tracker
(`predictive`), the outlines (`predictive@shaped_tracker`) and the registered velocities
(`predictive@registered_tracker`) side by side, their tracking quality against the truth,
their success with its interval and the skill over the blind floor, and the privileged
rung (`oracle_present`, the true present state) beside.

Where a tracker's folders hold no `predictive` rows of their own (the sets without a
static field, where the circle tracker's committed recall was right), its row is the one
of the set's committed ladder folder, hard worlds, the same 10 trials.
"""

from __future__ import annotations

from collections.abc import Callable

from collision_anatomy import KINDS, SIDES
from tracker_sweeps import PRESETS, SETS, folder

LADDERS = {
    "imported_worlds": ("the release's 60", "original60_barn"),
    "paper60": ("paper60", "paper60_barn"),
    "tier-dense": ("`tier-dense`", "tier_dense_barn"),
    "tier-fast": ("`tier-fast`", "tier_fast_barn"),
    "tier-mixed": ("`tier-mixed`", "tier_mixed_barn"),
    "tier-combined": ("`tier-combined`", "tier_combined_barn"),
}
"""Each swept set (`tracker_sweeps.SETS`, in whose order the table lists them): (its name in
the table, its committed ladder folder)."""
TRACKER_FOLDERS = {folder(preset, world_set): (preset, world_set) for preset in PRESETS for world_set in SETS}
"""Every tracker sweep's folder: (its preset, its set)."""
TRACKERS = (
    ("predictive", "circles (`kalman`)"),
    ("predictive@shaped_tracker", "outlines (`shaped`)"),
    ("predictive@registered_tracker", "registered velocity (`registered`)"),
)
"""The trackers' table's rows: `predictive` with each tracker."""
TEB_PADDING = (
    ("teb@teb_dynamic", "radius only (`teb@teb_dynamic`)"),
    ("teb@teb_dynamic_uncertain", "radius + 1 std (`teb@teb_dynamic_uncertain`)"),
)
"""The uncertainty table's rows: TEB planning against each track's radius, and grown by its
uncertainty."""


def _tracking(s: dict) -> str:
    if s.get("track_recall") is None:
        return "- | - | - | - | -"
    return (
        f"{s['track_recall']:.3f} | {s['track_precision']:.3f} | "
        f"{1000 * s['track_pos_err']:.1f} / {1000 * s['track_pos_err_p95']:.0f} | "
        f"{s['track_vel_err_p95']:.2f} | {s['track_id_switches']:.1f}"
    )


def tracker_table(
    folders: dict[str, tuple[list[dict], list[dict]]],
    ci: Callable[[dict], str],
    skill: Callable[[dict], str],
    rows: tuple[tuple[str, str], ...] = TRACKERS,
    what: str = "tracker",
) -> str:
    """The table of `rows` (planner, its name in the table; `what` heads the column);
    `folders` maps a results folder to (rows, summary); `ci` and `skill` are the pages'
    formatters of a summary row's success interval and skill over the floor."""
    lines = [
        f"| worlds (hard) | {what} | success [95% CI] | skill over floor | recall | precision "
        "| position error median / p95 [mm] | velocity error p95 [m/s] | identity switches per episode "
        "| `oracle_present` (privileged) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for world_set in SETS:
        hard = hard_summaries(folders, world_set)
        if hard is None:
            continue
        privileged = hard.get("oracle_present")
        beside = ci(privileged) if privileged else "-"
        for planner, tracker in rows:
            s = hard.get(planner)
            if s is None:
                continue
            lines.append(f"| {LADDERS[world_set][0]} | {tracker} | {ci(s)} | {skill(s)} | {_tracking(s)} | {beside} |")
    return "\n".join(lines)


def hard_summaries(folders: dict[str, tuple[list[dict], list[dict]]], world_set: str) -> dict[str, dict] | None:
    """A swept set's summary rows of its hard worlds by planner: the tracker sweeps' own rows
    first (the circle tracker's re-scored recall), then its ladder folder's (the privileged
    rungs, and the trackers no sweep re-ran there); None where no tracker sweep of the set is
    committed."""
    own: dict = {}
    for preset in reversed(PRESETS):
        summary = folders.get(folder(preset, world_set), ([], []))[1]
        own |= {s["planner"]: s for s in summary if s["difficulty"] == "hard"}
    if not own:
        return None
    ladder = LADDERS[world_set][1]
    base = {s["planner"]: s for s in folders.get(ladder, ([], []))[1] if s["difficulty"] == "hard"}
    return base | own


def validation_table(record: dict | None) -> str:
    """The trackers on validation worlds (`benchmarks/tracker_validation.py`'s record):
    per tier's profile, each tracker's medians over episodes."""
    if not record:
        return "(no record: run `python benchmarks/tracker_validation.py`)"
    lines = [
        "| profile | tracker | recall | precision | position error median / p95 [mm] "
        "| velocity error p95 [m/s] | identity switches: matched afresh each tick / CLEAR-MOT |",
        "|---|---|---|---|---|---|---|",
    ]
    for tier, kinds in record["tiers"].items():
        for kind, m in kinds.items():
            lines.append(
                f"| `{tier}` | `{kind}` | {m['recall']:.3f} | {m['precision']:.3f} | "
                f"{1000 * m['position_error_median']:.1f} / {1000 * m['position_error_p95']:.0f} | "
                f"{m['velocity_error_p95']:.2f} | {m['id_switches']:.1f} / {m['id_switches_mot']:.1f} |"
            )
    return "\n".join(lines)


GAP_RUNGS = {
    "laser": "the tracker's tracks (`predictive`)",
    "velocity": "matched tracks given the true velocity",
    "state": "... and the true centre and bounding radius",
    "state_exact": "... and no uncertainty padding",
    "seen": "... and the tracks that match no obstacle left out",
    "oracle_present": "every obstacle's true state, seen or not (`oracle_present`)",
}
"""`benchmarks/perception_gap.py`'s rungs, in order, as the table names them."""


def success_cell(ends: dict[str, int], wilson: Callable[[int, int], tuple[float, float]]) -> str:
    """How a setting's episodes ended ({outcome: count}) as its success with its interval."""
    n, wins = sum(ends.values()), ends.get("success", 0)
    low, high = wilson(wins, n)
    return f"{wins / n:.2f} [{low:.2f}, {high:.2f}]"


def gap_table(record: dict | None, wilson: Callable[[int, int], tuple[float, float]]) -> str:
    """`predictive`'s gap to `oracle_present` split rung by rung (`perception_gap.py`'s
    record), a column per tracker; `wilson` gives a success count's interval."""
    if not record:
        return "(no record: run `python benchmarks/perception_gap.py --record`)"
    trackers = list(record["trackers"])
    lines = [
        "| tracks planned against | " + " | ".join(f"`{t}` tracker" for t in trackers) + " |",
        "|---|" + "---|" * len(trackers),
    ]
    for rung, what in GAP_RUNGS.items():
        cells = []
        for tracker in trackers:
            ends = record["trackers"][tracker].get(rung)
            cells.append(success_cell(ends, wilson) if ends else "-")
        lines.append(f"| {what} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def padding_table(record: dict | None, wilson: Callable[[int, int], tuple[float, float]]) -> str:
    """Each planner's success with the uncertainty padding off and on, on the same validation
    episodes (`uncertainty_padding.py`'s record); `wilson` gives a success count's interval."""
    if not record:
        return "(no record: run `python benchmarks/uncertainty_padding.py --record`)"
    padding = record["padding"]
    on = f"radius + {padding['uncertainty_sigmas']:g} std (at most {padding['max_padding']:g} m)"
    lines = [
        f"| profile | planner | radius only | {on} | episodes the padding won / lost |",
        "|---|---|---|---|---|",
    ]
    for tier, planners in sorted(record["tiers"].items()):
        for planner, row in planners.items():
            cells = [success_cell(row[setting], wilson) for setting in ("off", "on")]
            flips = row["paired"]
            lines.append(f"| `{tier}` | `{planner}` | {cells[0]} | {cells[1]} | {flips['won']} / {flips['lost']} |")
    return "\n".join(lines)


def anatomy_table(record: dict | None) -> str:
    """`predictive`'s collisions by what its tracker knew of the obstacle that hit it and where
    that came from (`collision_anatomy.py`'s record): each cell the collisions, and in
    brackets those `oracle_present` survived (the gap's share)."""
    if not record:
        return "(no record: run `python benchmarks/collision_anatomy.py --record`)"
    kinds, sides = KINDS, SIDES
    hits = [e for e in record["episodes"] if e["kind"] != "-"]
    lines = [
        "| the obstacle that hit, in its last second | "
        + " | ".join(f"from the {s}" if s != "behind" else "from behind (outside the laser's view)" for s in sides)
        + " | all |",
        "|---|" + "---|" * (len(sides) + 1),
    ]

    def cell(chosen: list[dict]) -> str:
        return f"{len(chosen)} ({sum(e['oracle_present'] == 'success' for e in chosen)})"

    for kind in (*kinds, None):
        of_kind = [e for e in hits if kind is None or e["kind"] == kind]
        label = "every collision" if kind is None else kind
        lines.append(
            f"| {label} | "
            + " | ".join(cell([e for e in of_kind if e["side"] == s]) for s in sides)
            + f" | {cell(of_kind)} |"
        )
    return "\n".join(lines)
