"""Where `predictive` loses to `oracle_present` (issue 57): the gap split by what the
laser tracker gets wrong, on validation worlds (never the evaluation sets).

Each rung below is `predictive`'s search fed tracks that are a little more true than the
one before; every rung is privileged (it reads the true obstacle states to correct the
tracks), so these are diagnostics, not planners:

- `laser`: `predictive` as shipped (the tracker's tracks);
- `velocity`: the tracker's tracks, each matched track (one to one, within 1 m of a true
  centre, as the tracking metrics match them) given its obstacle's true velocity;
- `state`: matched tracks given their obstacle's true centre, velocity and bounding radius
  (the tracker's uncertainty still pads them);
- `state_exact`: as `state`, with no padding (zero uncertainty) on the matched tracks;
- `seen`: as `state_exact`, and the tracks that match no obstacle left out: the true
  states of what the laser has seen;
- `oracle_present`: every obstacle's true state, seen or not.

Besides these, `velocity_young`, `velocity_coasting`, `velocity_shaped` and
`velocity_seen_old` give the true velocity only to the matched tracks younger than
0.35 s, coasting, of boxes and capsules (bounding radius over 0.51 m), or seen now and
older, to say which velocities matter.

`python benchmarks/perception_gap.py --record` runs every rung with the `kalman` and the
`registered` tracker on 60 hard validation worlds of `tier-combined`'s profile (seed 5700),
one trial, prints each rung's success with its interval and how its episodes ended, and
writes results/perception_gap/tier-combined.json (about 15 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from tracker_validation import SEED, check_arguments, validation_worlds

from dynabarn.bench.stats import wilson_interval
from dynabarn.files import write_atomically
from dynabarn.perception import Tracks
from dynabarn.planners import get_planner
from dynabarn.planners.predictive import PredictivePlanner
from dynabarn.protocol import get_protocol
from dynabarn.runner import EpisodeSpec, run_spec
from dynabarn.sim.track_scoring import matched_pairs

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "perception_gap"
RUNGS = ("laser", "velocity", "state", "state_exact", "seen", "oracle_present")


def corrected(tracks: Tracks, truth, rung: str) -> Tracks:
    """`tracks` with the matched ones made true as far as `rung` says."""
    if not len(tracks) or rung == "laser":
        return tracks
    rows, cols, _ = matched_pairs(tracks.positions, truth.positions)  # as the tracking metrics match
    positions, velocities, sizes = tracks.positions.copy(), tracks.velocities.copy(), tracks.sizes.copy()
    pos_var, vel_var, cov = tracks.position_var.copy(), tracks.velocity_var.copy(), tracks.position_velocity_cov.copy()
    if rung.startswith("velocity_"):
        now = tracks.time
        which = {
            "velocity_young": tracks.age[rows] < 0.35,
            "velocity_coasting": tracks.last_seen[rows] < now - 1e-6,
            "velocity_shaped": truth.radii[cols] > 0.51,
            "velocity_seen_old": (tracks.age[rows] >= 0.35) & (tracks.last_seen[rows] >= now - 1e-6),
        }[rung]
        rows, cols = rows[which], cols[which]
    velocities[rows] = truth.velocities[cols]
    if not rung.startswith("velocity"):
        positions[rows] = truth.positions[cols]
        sizes[rows] = truth.radii[cols]
    if rung in ("state_exact", "seen"):
        pos_var[rows], vel_var[rows], cov[rows] = 0.0, 0.0, 0.0
    keep = np.arange(len(tracks)) if rung != "seen" else np.sort(rows)
    return Tracks(
        time=tracks.time,
        ids=tracks.ids[keep],
        positions=positions[keep],
        velocities=velocities[keep],
        sizes=sizes[keep],
        position_var=pos_var[keep],
        velocity_var=vel_var[keep],
        position_velocity_cov=cov[keep],
        age=tracks.age[keep],
        last_seen=tracks.last_seen[keep],
    )


class Corrected(PredictivePlanner):
    """`predictive` whose tracks are corrected by the truth as `rung` says."""

    name = "corrected"
    privileged = True

    def __init__(self, rung: str, **config) -> None:
        super().__init__(**config)
        self.rung = rung

    def updated_tracks(self, obs):
        return corrected(super().updated_tracks(obs), obs.obstacles, self.rung)


def episode(task: tuple) -> tuple[str, str, str]:
    """One episode of a rung: (tracker, rung, outcome)."""
    folder, tracker, rung, world_id, seed, config = task
    planner = get_planner("oracle_present") if rung == "oracle_present" else Corrected(rung, **config)
    spec = EpisodeSpec.make(Path(folder) / f"world_{world_id:03d}.xml", planner.name, get_protocol("barn"), seed=seed)
    return tracker, rung, run_spec(spec, planner=planner).result.outcome.value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tier", default="tier-combined", help="tier whose profile is drawn (default: tier-combined)")
    parser.add_argument("--worlds", type=int, default=60, help="worlds from --first (default: 60)")
    parser.add_argument("--first", type=int, default=200, help="first world id (default: 200, the first hard one)")
    parser.add_argument("--trials", type=int, default=1, help="trials per world (default: 1)")
    parser.add_argument("--rungs", default=",".join(RUNGS), help=f"which rungs (default: {','.join(RUNGS)})")
    parser.add_argument("--trackers", default="kalman,registered", help="tracker kinds (default: kalman,registered)")
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="predictive's configuration (default: none)"
    )
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default: 2)")
    parser.add_argument("--record", action="store_true", help=f"write the table to {OUT.relative_to(ROOT)}/TIER.json")
    args = parser.parse_args(argv)
    config = {k: json.loads(v) if v[:1] in "-.0123456789[" else v for k, v in (a.split("=", 1) for a in args.set)}
    rungs, trackers = args.rungs.split(","), args.trackers.split(",")
    check_arguments(parser, [args.tier], [("predictive", config | {"tracker.kind": t}) for t in trackers])
    table: dict[str, dict[str, Counter]] = {t: {r: Counter() for r in rungs} for t in trackers}
    with tempfile.TemporaryDirectory(prefix="dynabarn-gap-") as scratch:
        folder = str(validation_worlds(args.tier, Path(scratch)))
        tasks = [
            (folder, tracker, rung, world_id, seed, config | {"tracker.kind": tracker})
            for tracker in trackers
            for rung in rungs
            for world_id in range(args.first, args.first + args.worlds)
            for seed in range(args.trials)
        ]
        with ProcessPoolExecutor(args.jobs) as pool:
            for tracker, rung, outcome in pool.map(episode, tasks, chunksize=4):
                table[tracker][rung][outcome] += 1
    for tracker in trackers:
        for rung in rungs:
            ends = table[tracker][rung]
            n = sum(ends.values())
            low, high = wilson_interval(ends["success"], n)
            print(f"{tracker:<11} {rung:<15} {ends['success'] / n:.2f} [{low:.2f}, {high:.2f}]  {dict(ends)}")
    if args.record:
        record = {
            "tier": args.tier,
            "seed": SEED,
            "worlds": [args.first, args.first + args.worlds - 1],
            "trials": args.trials,
            "config": config,
            "trackers": {t: {r: dict(sorted(c.items())) for r, c in rungs_.items()} for t, rungs_ in table.items()},
        }
        OUT.mkdir(parents=True, exist_ok=True)
        write_atomically(OUT / f"{args.tier}.json", json.dumps(record, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
