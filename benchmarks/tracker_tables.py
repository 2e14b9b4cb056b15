"""The shaped tracker's table (issue 57), from the committed sweeps of
`benchmarks/tracker_sweeps.py`: per world set's hard worlds, the circle tracker
(`predictive`) and the shaped one (`predictive@shaped_tracker`) side by side, their
tracking quality against the truth, their success with its interval and the skill over
the blind floor, and the privileged rung (`oracle_present`, the true present state) beside.

Where a shaped-tracker folder holds no `predictive` rows of its own (the sets without a
static field, where the circle tracker's committed recall was right), its row is the one
of the set's committed ladder folder, hard worlds, the same 10 trials.
"""

from __future__ import annotations

from collections.abc import Callable

SHAPED_SETS = {
    "shaped_tracker_paper60": ("paper60", "paper60_barn"),
    "shaped_tracker_tier_dense": ("`tier-dense`", "tier_dense_barn"),
    "shaped_tracker_tier_fast": ("`tier-fast`", "tier_fast_barn"),
    "shaped_tracker_tier_mixed": ("`tier-mixed`", "tier_mixed_barn"),
    "shaped_tracker_tier_combined": ("`tier-combined`", "tier_combined_barn"),
}
"""The shaped tracker's folders: (the set's name, its committed ladder folder)."""
TRACKERS = (("predictive", "circles (`kalman`)"), ("predictive@shaped_tracker", "outlines (`shaped`)"))


def _tracking(s: dict) -> str:
    if s.get("track_recall") is None:
        return "- | - | - | - | -"
    return (
        f"{s['track_recall']:.3f} | {s['track_precision']:.3f} | "
        f"{1000 * s['track_pos_err']:.1f} / {1000 * s['track_pos_err_p95']:.0f} | "
        f"{s['track_vel_err_p95']:.2f} | {s['track_id_switches']:.1f}"
    )


def shaped_tracker_table(
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
    for folder, (title, ladder) in SHAPED_SETS.items():
        own = {(s["planner"], s["difficulty"]): s for s in folders.get(folder, ([], []))[1]}
        base = {(s["planner"], s["difficulty"]): s for s in folders.get(ladder, ([], []))[1]}
        if not own:
            continue
        privileged = base.get(("oracle_present", "hard"))
        beside = ci(privileged) if privileged else "-"
        for planner, tracker in TRACKERS:
            s = own.get((planner, "hard")) or base.get((planner, "hard"))
            if s is None:
                continue
            lines.append(f"| {title} | {tracker} | {ci(s)} | {skill(s)} | {_tracking(s)} | {beside} |")
    return "\n".join(lines)
