"""The committed evaluation of the student that sees the map (issue 57): `dagger` driving
`dynabarn/policies/dagger_map.pt` on the hard worlds of every set it never trained on, the
trials of each set's committed sweep, so that its rows pair with that sweep's `dagger`
(the shipped student), `predictive` (the teacher), the privileged rungs and the floor,
episode by episode (`benchmarks/learning_tables.py`).

`python benchmarks/student_map_sweeps.py` runs what is missing (each sweep resumes) into
results/dagger_map_<folder>/; about 10 minutes on 2 cores. The release's 60 are imported
first from ../shared/reference when that is there (skipped, and said, where it is not).
"""

from __future__ import annotations

import sys
from pathlib import Path

from bench_command import import_release, run_dynabarn

POLICY = "dynabarn/policies/dagger_map.pt"
SWEEPS = (
    # (set, hard world ids, trials, the committed folder its rows pair with)
    ("imported_worlds", "40-59", 10, "original60_barn"),
    ("paper60", "200-219", 10, "paper60_barn"),
    ("dynabarn300", "220-299", 3, "unseen_barn"),
    ("tier-dense", "200-219", 10, "tier_dense_barn"),
    ("tier-fast", "200-219", 10, "tier_fast_barn"),
    ("tier-mixed", "200-219", 10, "tier_mixed_barn"),
    ("tier-combined", "200-219", 10, "tier_combined_barn"),
)


def main() -> int:
    released = import_release()
    for world_set, ids, trials, folder in SWEEPS:
        if world_set == "imported_worlds" and not released:
            continue
        out = Path("results") / f"dagger_map_{folder}"
        if run_dynabarn(
            "bench", "--set", world_set, "--worlds", ids, "--planner", "dagger", "--policy", POLICY,
            "--trials", str(trials), "--jobs", "2", "--out", str(out),
        ):  # fmt: skip
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
