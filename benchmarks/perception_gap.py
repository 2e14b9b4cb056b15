"""Where `predictive` loses to `oracle_present` (issue 57): the gap split by what the
laser tracker gets wrong, on validation worlds (never the evaluation sets).

Each rung below is `predictive`'s search fed tracks that are a little more true than the
one before; every rung is privileged (it reads the true obstacle states to correct the
tracks), so these are diagnostics, not planners:

- `laser`: `predictive` as shipped (the tracker's tracks);
- `velocity`: the tracker's tracks, each matched track (one to one, within 1 m of a true
  centre) given its obstacle's true velocity;
- `state`: matched tracks given their obstacle's true centre, velocity and bounding radius
  (the tracker's uncertainty still pads them);
- `state_exact`: as `state`, with no padding (zero uncertainty) on the matched tracks;
- `seen`: as `state_exact`, and the tracks that match no obstacle left out: the true
  states of what the laser has seen;
- `oracle_present`: every obstacle's true state, seen or not.

`python benchmarks/perception_gap.py [--tier tier-combined] [--worlds 20] [--trials 2]`
prints each rung's success with its interval and how its failures end.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from dynabarn.bench.stats import wilson_interval
from dynabarn.perception import Tracks
from dynabarn.planners import get_planner
from dynabarn.planners.predictive import PredictivePlanner
from dynabarn.protocol import get_protocol
from dynabarn.runner import EpisodeSpec, run_spec

RUNGS = ("laser", "velocity", "state", "state_exact", "seen", "oracle_present")


def corrected(tracks: Tracks, truth, rung: str) -> Tracks:
    """`tracks` with the matched ones made true as far as `rung` says."""
    if not len(tracks) or rung == "laser":
        return tracks
    d = np.sqrt(((tracks.positions[:, None] - truth.positions[None]) ** 2).sum(axis=-1))
    rows, cols = linear_sum_assignment(np.where(d <= 1.0, d, 1e6))
    ok = d[rows, cols] <= 1.0
    rows, cols = rows[ok], cols[ok]
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

    def obstacle_future(self, obs):
        tracks = corrected(self.tracker.update(obs.time, obs.scan, obs.pose), obs.obstacles, self.rung)
        self._tracks = tracks
        c = self.cfg
        times = obs.time + self._steps
        padding = np.minimum(c.max_padding, c.uncertainty_sigmas * tracks.position_std(times))
        return tracks.predict(times), tracks.sizes[None, :] + padding


def main(argv: list[str] | None = None) -> int:
    from tracker_validation import validation_worlds

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tier", default="tier-combined", help="tier whose profile is drawn (default: tier-combined)")
    parser.add_argument("--worlds", type=int, default=20, help="worlds from --first (default: 20)")
    parser.add_argument("--first", type=int, default=200, help="first world id (default: 200, the first hard one)")
    parser.add_argument("--trials", type=int, default=2, help="trials per world (default: 2)")
    parser.add_argument("--rungs", default=",".join(RUNGS), help=f"which rungs (default: {','.join(RUNGS)})")
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="predictive's configuration (default: none)"
    )
    args = parser.parse_args(argv)
    config = {k: json.loads(v) if v[:1] in "-.0123456789[" else v for k, v in (a.split("=", 1) for a in args.set)}
    with tempfile.TemporaryDirectory(prefix="dynabarn-gap-") as scratch:
        folder = validation_worlds(args.tier, Path(scratch))
        for rung in args.rungs.split(","):
            ends: Counter = Counter()
            for world_id in range(args.first, args.first + args.worlds):
                for seed in range(args.trials):
                    planner = get_planner("oracle_present") if rung == "oracle_present" else Corrected(rung, **config)
                    spec = EpisodeSpec.make(
                        folder / f"world_{world_id:03d}.xml", planner.name, get_protocol("barn"), seed=seed
                    )
                    ends[run_spec(spec, planner=planner).result.outcome] += 1
            n = sum(ends.values())
            low, high = wilson_interval(ends["success"], n)
            print(f"{rung:<15} {ends['success'] / n:.2f} [{low:.2f}, {high:.2f}]  {dict(ends)}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
