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

from tracker_sweeps import PRESETS, SETS, folder

LADDERS = {
    "paper60": ("paper60", "paper60_barn"),
    "tier-dense": ("`tier-dense`", "tier_dense_barn"),
    "tier-fast": ("`tier-fast`", "tier_fast_barn"),
    "tier-mixed": ("`tier-mixed`", "tier_mixed_barn"),
    "tier-combined": ("`tier-combined`", "tier_combined_barn"),
}
"""Each swept set: (its name in the table, its committed ladder folder)."""
TRACKER_FOLDERS = {folder(preset, world_set): (preset, world_set) for preset in PRESETS for world_set in SETS}
"""Every tracker sweep's folder: (its preset, its set)."""
TRACKERS = (
    ("predictive", "circles (`kalman`)"),
    ("predictive@shaped_tracker", "outlines (`shaped`)"),
    ("predictive@registered_tracker", "registered velocity (`registered`)"),
)


def _tracking(s: dict) -> str:
    if s.get("track_recall") is None:
        return "- | - | - | - | -"
    return (
        f"{s['track_recall']:.3f} | {s['track_precision']:.3f} | "
        f"{1000 * s['track_pos_err']:.1f} / {1000 * s['track_pos_err_p95']:.0f} | "
        f"{s['track_vel_err_p95']:.2f} | {s['track_id_switches']:.1f}"
    )


def tracker_table(
    folders: dict[str, tuple[list[dict], list[dict]]], ci: Callable[[dict], str], skill: Callable[[dict], str]
) -> str:
    """The table; `folders` maps a results folder to (rows, summary); `ci` and `skill` are
    the pages' formatters of a summary row's success interval and skill over the floor."""
    lines = [
        "| worlds (hard) | tracker | success [95% CI] | skill over floor | recall | precision "
        "| position error median / p95 [mm] | velocity error p95 [m/s] | identity switches per episode "
        "| `oracle_present` (privileged) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for world_set, (title, ladder) in LADDERS.items():
        own: dict = {}  # the sweeps' rows first (the circle tracker's re-scored recall), then the ladder's
        for preset in reversed(PRESETS):
            own |= {(s["planner"], s["difficulty"]): s for s in folders.get(folder(preset, world_set), ([], []))[1]}
        if not own:
            continue
        base = {(s["planner"], s["difficulty"]): s for s in folders.get(ladder, ([], []))[1]}
        privileged = base.get(("oracle_present", "hard"))
        beside = ci(privileged) if privileged else "-"
        for planner, tracker in TRACKERS:
            s = own.get((planner, "hard")) or base.get((planner, "hard"))
            if s is None:
                continue
            lines.append(f"| {title} | {tracker} | {ci(s)} | {skill(s)} | {_tracking(s)} | {beside} |")
    return "\n".join(lines)
