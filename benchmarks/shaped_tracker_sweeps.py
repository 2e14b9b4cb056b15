"""The committed evaluation of the shaped tracker (issue 57): `predictive@shaped_tracker`
on the hard worlds (ids 200-219) of every tier and of `paper60`, 10 trials, and on the
two tiers with a static field `predictive` (the circle tracker) again beside it, since
its committed tracking recall counted obstacles hidden behind static cylinders as in view
(fixed in the same issue; its successes are unchanged).

`python benchmarks/shaped_tracker_sweeps.py` runs what is missing (each sweep resumes)
into results/shaped_tracker_<set>/; about 40 minutes on 2 cores.
"""

from __future__ import annotations

import sys

from bench_command import ROOT, run_dynabarn

SWEEPS = (
    ("tier-combined", "predictive@shaped_tracker,predictive"),
    ("tier-mixed", "predictive@shaped_tracker,predictive"),
    ("tier-dense", "predictive@shaped_tracker"),
    ("tier-fast", "predictive@shaped_tracker"),
    ("paper60", "predictive@shaped_tracker"),
)
HARD = "200-219"


def main() -> int:
    for world_set, planners in SWEEPS:
        out = ROOT / "results" / f"shaped_tracker_{world_set.replace('-', '_')}"
        if run_dynabarn(
            "bench", "--set", world_set, "--worlds", HARD,
            "--planner", planners, "--trials", "10", "--jobs", "2", "--out", str(out.relative_to(ROOT)),
        ):  # fmt: skip
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
