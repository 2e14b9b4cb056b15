"""The committed evaluations of the laser trackers beyond the circle tracker (issue 57):
`predictive@PRESET` on the hard worlds (ids 200-219) of every tier and of `paper60`, 10
trials, into results/PRESET_<set>/ (`shaped_tracker`: outlines; `registered_tracker`:
velocity from registered returns).

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

from bench_command import run_dynabarn

SETS = ("tier-combined", "tier-mixed", "tier-dense", "tier-fast", "paper60")
PRESETS = ("shaped_tracker", "registered_tracker")
CIRCLES_AGAIN = {("shaped_tracker", "tier-combined"), ("shaped_tracker", "tier-mixed")}
"""The sweeps that ran the circle tracker again beside the preset."""
HARD = "200-219"


def folder(preset: str, world_set: str) -> str:
    """A preset's sweep folder of a set, under results/."""
    return f"{preset}_{world_set.replace('-', '_')}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("presets", nargs="*", help=f"which of {', '.join(PRESETS)} (default: every one)")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.presets) - set(PRESETS))
    if unknown:
        parser.error(f"unknown preset(s) {unknown}; known: {', '.join(PRESETS)}")
    for preset in args.presets or PRESETS:
        for world_set in SETS:
            planners = f"predictive@{preset}" + (",predictive" if (preset, world_set) in CIRCLES_AGAIN else "")
            if run_dynabarn(
                "bench", "--set", world_set, "--worlds", HARD,
                "--planner", planners, "--trials", "10", "--jobs", "2",
                "--out", f"results/{folder(preset, world_set)}",
            ):  # fmt: skip
                return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
