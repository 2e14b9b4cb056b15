"""The committed evaluations of the laser trackers beyond the circle tracker and of planning
against their uncertainty (issue 57): `PLANNER@PRESET` on the hard worlds of every tier, of
`paper60` (ids 200-219) and of the release's 60 (ids 40-59, imported first from
../shared/reference where that is there), 10 trials, into results/PRESET_<set>/
(`predictive@shaped_tracker`: outlines; `predictive@registered_tracker`: velocity from
registered returns; `teb@teb_dynamic_uncertain`: TEB's band kept clear of each track grown
by its uncertainty).

With the shaped tracker's sweeps, on the two tiers with a static field, `predictive` (the
circle tracker) ran again beside it, since its committed tracking recall counted obstacles
hidden behind static cylinders as in view (fixed in the same issue; its successes are
unchanged).

`python benchmarks/tracker_sweeps.py [PRESET ...]` runs what is missing (each sweep
resumes); about 40 minutes a preset on 2 cores. Without a preset: every one.
"""

from __future__ import annotations

import argparse
import sys

from bench_command import import_release, run_dynabarn

SETS = {
    # set: (its hard worlds, its name in folders), from the paper's worlds to the hardest tier
    "imported_worlds": ("40-59", "original60"),  # the release's 60, where ../shared/reference has them
    "paper60": ("200-219", "paper60"),
    "tier-dense": ("200-219", "tier_dense"),
    "tier-fast": ("200-219", "tier_fast"),
    "tier-mixed": ("200-219", "tier_mixed"),
    "tier-combined": ("200-219", "tier_combined"),
}
PRESETS = {"shaped_tracker": "predictive", "registered_tracker": "predictive", "teb_dynamic_uncertain": "teb"}
"""Each swept preset: the planner it is run with."""
CIRCLES_AGAIN = {("shaped_tracker", "tier-combined"), ("shaped_tracker", "tier-mixed")}
"""The sweeps that ran the circle tracker again beside the preset."""


def folder(preset: str, world_set: str) -> str:
    """A preset's sweep folder of a set, under results/."""
    return f"{preset}_{SETS[world_set][1]}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("presets", nargs="*", help=f"which of {', '.join(PRESETS)} (default: every one)")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.presets) - set(PRESETS))
    if unknown:
        parser.error(f"unknown preset(s) {unknown}; known: {', '.join(PRESETS)}")
    released = import_release()
    for preset in args.presets or PRESETS:
        for world_set, (hard, _) in SETS.items():
            if world_set == "imported_worlds" and not released:
                continue
            planners = f"{PRESETS[preset]}@{preset}" + (",predictive" if (preset, world_set) in CIRCLES_AGAIN else "")
            if run_dynabarn(
                "bench", "--set", world_set, "--worlds", hard,
                "--planner", planners, "--trials", "10", "--jobs", "2",
                "--out", f"results/{folder(preset, world_set)}",
            ):  # fmt: skip
                return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
