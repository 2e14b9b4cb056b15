"""Students and their references on the same validation worlds: the ablation table of the
DAgger student (issue 44).

    python benchmarks/student_validation.py NAME=POLICY.pt [NAME=PLANNER ...] [--worlds 60]
        [--profile-sets table1,release2022] [--jobs 2] [--out FILE.json]

Every entry drives the same procedural validation worlds (the split's own seed namespace,
`learn.split.VALIDATION_SEED_BASE`: never a training world of any run, never an evaluation
set), one trial each (the trial seed is the world's index): a student's policy file
(`dagger` with `policy=FILE`) or a planner by name (`oracle_present`, its teacher;
`predictive`; `straight`, the floor). Worlds are drawn from the profile sets or tiers given
(`--profile-sets`), so a run that trained on tiers' profiles and one that did not are
compared on the same worlds. Prints success per difficulty with Wilson intervals and writes
them to --out (JSON) when given.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

from dynabarn.bench.summary import wilson_interval
from dynabarn.files import write_atomically
from dynabarn.learn.split import ProceduralWorlds, training_profile
from dynabarn.processes import map_in_workers, usable_cores
from dynabarn.protocol import get_protocol
from dynabarn.runner import EpisodeSpec, run_spec


def _episode(item: tuple[str, str, str, tuple[str, ...], int]) -> tuple[str, str, bool]:
    """(entry, difficulty, success) of one entry in validation world k."""
    name, what, folder, profile_sets, k = item
    world = ProceduralWorlds(Path(folder) / f"w{k}", split="validation", profile_sets=profile_sets).world(k)
    planner, config = ("dagger", {"policy": what}) if what.endswith(".pt") else (what, {})
    result = run_spec(EpisodeSpec.make(world.path, planner, get_protocol("barn"), config=config, seed=k)).result
    return name, world.difficulty, result.outcome.value == "success"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("entries", nargs="+", help="NAME=POLICY.pt (a student) or NAME=PLANNER (a planner by name)")
    parser.add_argument("--worlds", type=int, default=60, help="validation worlds (default: 60)")
    parser.add_argument("--profile-sets", default="table1,release2022", help="profile sets or tiers to draw from")
    parser.add_argument("--jobs", type=int, default=usable_cores(), help="worker processes (default: usable cores)")
    parser.add_argument("--out", type=Path, help="write the table's numbers here (JSON)")
    args = parser.parse_args(argv)
    profile_sets = tuple(p for p in args.profile_sets.split(",") if p)
    for name in profile_sets:
        training_profile(name)
    entries = dict(e.split("=", 1) for e in args.entries)
    counts: dict[str, dict[str, list[int]]] = defaultdict(lambda: defaultdict(lambda: [0, 0]))
    with tempfile.TemporaryDirectory() as tmp:
        items = [(n, w, tmp, profile_sets, k) for n, w in entries.items() for k in range(args.worlds)]
        for i, (name, difficulty, won) in enumerate(map_in_workers(_episode, items, args.jobs), 1):
            for d in (difficulty, "all"):
                counts[name][d][0] += won
                counts[name][d][1] += 1
            print(f"\r{i}/{len(items)} episodes", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    table = {}
    print(f"validation worlds 0-{args.worlds - 1} of {', '.join(profile_sets)}, one trial each")
    print(f"{'entry':<24}" + "".join(f"{d:>22}" for d in ("easy", "medium", "hard", "all")))
    for name in entries:
        row = {}
        for d in ("easy", "medium", "hard", "all"):
            k, n = counts[name][d]
            lo, hi = wilson_interval(k, n) if n else (float("nan"), float("nan"))
            row[d] = {"successes": k, "episodes": n, "rate": k / n if n else None, "interval": [lo, hi]}
        table[name] = row
        cells = [
            f"{row[d]['rate']:.2f} [{row[d]['interval'][0]:.2f}, {row[d]['interval'][1]:.2f}]"
            if row[d]["episodes"]
            else "-"
            for d in ("easy", "medium", "hard", "all")
        ]
        print(f"{name:<24}" + "".join(f"{c:>22}" for c in cells))
    if args.out is not None:
        shas = {n: hashlib.sha256(Path(w).read_bytes()).hexdigest() for n, w in entries.items() if w.endswith(".pt")}
        record = {"worlds": args.worlds, "profile_sets": list(profile_sets), "entries": entries, "policy_sha256": shas}
        record["success"] = table
        write_atomically(args.out, json.dumps(record, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
