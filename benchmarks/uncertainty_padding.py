"""What planning against the tracker's uncertainty buys (issue 57, part 2), on validation
worlds (never the evaluation sets).

Every planner that predicts tracks can keep clear of each track's radius grown by
`uncertainty_sigmas` standard deviations of its predicted position, at most `max_padding`
(`Tracks.padded_sizes`): `predictive` does by default (1 sigma, at most 0.3 m), `dwa` and
`teb` with `include_dynamic_obstacles` only when asked. Each planner runs here with the
padding off and on (1 sigma, at most 0.3 m) on the hard worlds of each tier's profile drawn
under the validation seed (5700), paired: the same worlds and trials.

`python benchmarks/uncertainty_padding.py --record` writes
results/uncertainty_padding/validation.json and prints the table (about 25 minutes on 2
cores); its table is generated on docs/concepts/perception.md (block `uncertainty-padding`).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from tracker_tables import success_cell
from tracker_validation import SEED, check_arguments, validation_worlds

from dynabarn.bench.stats import wilson_interval
from dynabarn.files import write_atomically
from dynabarn.planners import get_planner
from dynabarn.planners.tracking import UncertaintyPadding
from dynabarn.protocol import get_protocol
from dynabarn.runner import EpisodeSpec, run_spec

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "uncertainty_padding" / "validation.json"
PLANNERS = {
    # planner: its configuration besides the padding (the sweeps' presets: dwa_dynamic, teb_dynamic)
    "predictive": {},
    "dwa": {"include_dynamic_obstacles": True},
    "teb": {"include_dynamic_obstacles": True},
}
SIGMAS = (0.0, 1.0)
"""The padding off and on (`uncertainty_sigmas`; `max_padding` at its default, 0.3 m)."""


def episode(task: tuple) -> tuple[tuple[str, str, float], tuple[int, int], str]:
    """One episode: ((tier, planner, sigmas), (world id, seed), outcome)."""
    tier, folder, planner_name, sigmas, world_id, seed = task
    planner = get_planner(planner_name, **PLANNERS[planner_name], uncertainty_sigmas=sigmas)
    spec = EpisodeSpec.make(Path(folder) / f"world_{world_id:03d}.xml", planner.name, get_protocol("barn"), seed=seed)
    return (tier, planner_name, sigmas), (world_id, seed), run_spec(spec, planner=planner).result.outcome.value


def summary(outcomes: dict[tuple[int, int], str]) -> dict[str, int]:
    """How a setting's episodes ended: {outcome: count}."""
    return dict(sorted(Counter(outcomes.values()).items()))


def paired(off: dict[tuple[int, int], str], on: dict[tuple[int, int], str]) -> dict[str, int]:
    """The same episodes with the padding off and on: how many it won and lost."""
    return {
        "won": sum(off[k] != "success" and on[k] == "success" for k in off),
        "lost": sum(off[k] == "success" and on[k] != "success" for k in off),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--tiers", default="tier-mixed,tier-combined", help="profiles drawn (default: tier-mixed,tier-combined)"
    )
    parser.add_argument("--planners", default=",".join(PLANNERS), help=f"which (default: {','.join(PLANNERS)})")
    parser.add_argument("--worlds", type=int, default=100, help="hard worlds from id 200 (default: 100)")
    parser.add_argument("--trials", type=int, default=2, help="trials per world (default: 2)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default: 2)")
    parser.add_argument("--record", action="store_true", help=f"write {OUT.relative_to(ROOT)}")
    args = parser.parse_args(argv)
    tiers, planners = args.tiers.split(","), args.planners.split(",")
    unknown = sorted(set(planners) - set(PLANNERS))
    if unknown:
        parser.error(f"unknown planner(s) {unknown}; known: {', '.join(PLANNERS)}")
    check_arguments(parser, tiers, [])
    ends: dict[tuple[str, str, float], dict[tuple[int, int], str]] = {
        (t, p, s): {} for t in tiers for p in planners for s in SIGMAS
    }
    with tempfile.TemporaryDirectory(prefix="dynabarn-padding-") as scratch:
        tasks = [
            (tier, str(validation_worlds(tier, Path(scratch))), planner, sigmas, world_id, seed)
            for tier in tiers
            for planner in planners
            for sigmas in SIGMAS
            for world_id in range(200, 200 + args.worlds)
            for seed in range(args.trials)
        ]
        with ProcessPoolExecutor(args.jobs) as pool:
            for setting, key, outcome in pool.map(episode, tasks, chunksize=4):
                ends[setting][key] = outcome
    record: dict[str, dict] = {t: {} for t in tiers}
    for tier in tiers:
        for planner in planners:
            off, on = (ends[tier, planner, s] for s in SIGMAS)
            record[tier][planner] = {"off": summary(off), "on": summary(on), "paired": paired(off, on)}
            cells = [success_cell(record[tier][planner][setting], wilson_interval) for setting in ("off", "on")]
            flips = record[tier][planner]["paired"]
            print(f"{tier:<14} {planner:<11} off {cells[0]}  on {cells[1]}  won {flips['won']} lost {flips['lost']}")
    if args.record:
        document = {
            "seed": SEED,
            "worlds": [200, 200 + args.worlds - 1],
            "trials": args.trials,
            "padding": {"uncertainty_sigmas": SIGMAS[1], "max_padding": UncertaintyPadding().max_padding},
            "planners": {p: PLANNERS[p] for p in planners},
            "tiers": record,
        }
        OUT.parent.mkdir(parents=True, exist_ok=True)
        write_atomically(OUT, json.dumps(document, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
