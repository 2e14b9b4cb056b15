"""What hit `predictive` (issue 57): each collision on validation worlds (never the
evaluation sets) classified by what the tracker knew of the obstacle that hit the robot in
the last second before contact, and by where it came from, beside whether
`oracle_present` (the true present state) survived the same episode.

The obstacle named in the collision's reason is followed over the last ten ticks (an
episode observer sees each tick's true obstacles and the planner's tracks, matched one to
one within 1 m as the tracking metrics match them):

- `untracked`: no track matched it before the last tick;
- `lost`: matched earlier in that second, not in either of the last two ticks;
- `centre off`: matched, its track's centre more than 0.45 m off at contact (an outline
  the circle does not cover);
- `velocity off`: matched, its track's velocity more than 1 m/s off at one of the last five
  ticks (the obstacle's from its positions a tick apart);
- `tracked`: matched, centre and velocity within those at contact.

Where it came from: its bearing from the robot's heading at contact, `front` (within
90 degrees), `side` (90-135 degrees, the laser's edge) or `behind` (beyond 135 degrees,
outside the laser's field of view).

`python benchmarks/collision_anatomy.py --record` runs `predictive@registered_tracker` and
`oracle_present` on 100 hard validation worlds of `tier-combined`'s profile (seed 5700),
one trial, writes results/perception_gap/collisions_tier-combined.json and prints the
table (about 4 minutes on 2 cores); the table is generated on docs/concepts/perception.md
(block `collision-anatomy`).
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from collections import Counter, deque
from concurrent.futures import ProcessPoolExecutor
from itertools import pairwise
from pathlib import Path

import numpy as np
from tracker_validation import SEED, check_arguments, validation_worlds

from dynabarn.files import write_atomically
from dynabarn.interfaces import EpisodeObserver
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.runner import EpisodeSpec, run_spec
from dynabarn.sim.track_scoring import matched_pairs

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "perception_gap"
TICKS = 10
"""Ticks followed before contact (one second at the control rate)."""
CENTRE_OFF = 0.45
"""[m] A track's centre this far from its obstacle's at contact: `centre off`."""
VELOCITY_OFF = 1.0
"""[m/s] A track's velocity this far from its obstacle's: `velocity off`."""
KINDS = ("untracked", "lost", "centre off", "velocity off", "tracked")
SIDES = ("front", "side", "behind")


class LastSecond(EpisodeObserver):
    """Keeps the last `TICKS` ticks' true obstacles, tracks and robot pose."""

    def __init__(self) -> None:
        self.ticks: deque = deque(maxlen=TICKS + 1)

    def on_tick(self, tick) -> None:
        self.ticks.append((tick.time, np.asarray(tick.obstacles).copy(), tick.tracks, np.asarray(tick.pose).copy()))


def classify(ticks: list, hit: int) -> tuple[str, str]:
    """(kind, side) of obstacle `hit` over the kept ticks (the first gives the second's
    true velocity only)."""
    states = []  # per tick: None, or (centre error, velocity error)
    for (t0, before, _, _), (t1, truth, tracks, _) in pairwise(ticks):
        if tracks is None or not len(tracks):
            states.append(None)
            continue
        rows, cols, _ = matched_pairs(tracks.positions, truth)
        at = np.flatnonzero(cols == hit)
        if not len(at):
            states.append(None)
            continue
        row = rows[at[0]]
        velocity = (truth[hit] - before[hit]) / max(t1 - t0, 1e-9)
        states.append(
            (
                float(np.hypot(*(tracks.positions[row] - truth[hit]))),
                float(np.hypot(*(tracks.velocities[row] - velocity))),
            )
        )
    if all(s is None for s in states[:-1]):
        kind = "untracked"
    elif states[-1] is None and states[-2] is None:
        kind = "lost"
    else:
        last = states[-1] if states[-1] is not None else states[-2]
        if last[0] > CENTRE_OFF:
            kind = "centre off"
        elif max(s[1] for s in states[-5:] if s is not None) > VELOCITY_OFF:
            kind = "velocity off"
        else:
            kind = "tracked"
    _, truth, _, pose = ticks[-1]
    rel = truth[hit] - pose[:2]
    bearing = abs((math.atan2(rel[1], rel[0]) - pose[2] + math.pi) % (2.0 * math.pi) - math.pi)
    side = "front" if bearing <= math.pi / 2 else ("side" if bearing <= 3 * math.pi / 4 else "behind")
    return kind, side


def episode(task: tuple) -> tuple[int, str, str, str]:
    """One world: (world id, `oracle_present`'s outcome, kind, side); kind and side '-'
    where `predictive` did not hit a moving obstacle."""
    folder, world_id, config = task
    world = Path(folder) / f"world_{world_id:03d}.xml"
    oracle = get_planner("oracle_present")
    present = run_spec(EpisodeSpec.make(world, oracle.name, get_protocol("barn"), seed=0), planner=oracle).result
    planner, watch = get_planner("predictive", **config), LastSecond()
    spec = EpisodeSpec.make(world, planner.name, get_protocol("barn"), seed=0)
    result = run_spec(spec, planner=planner, observers=[watch]).result
    if result.outcome.value != "collision" or "obstacle_" not in result.reason or len(watch.ticks) < 3:
        return world_id, present.outcome.value, "-", result.outcome.value
    hit = int(result.reason.split("obstacle_")[1].split()[0])
    return world_id, present.outcome.value, *classify(list(watch.ticks), hit)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tier", default="tier-combined", help="tier whose profile is drawn (default: tier-combined)")
    parser.add_argument("--worlds", type=int, default=100, help="hard worlds from id 200 (default: 100)")
    parser.add_argument("--tracker", default="registered", help="predictive's tracker.kind (default: registered)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default: 2)")
    parser.add_argument("--record", action="store_true", help=f"write {OUT.relative_to(ROOT)}/collisions_TIER.json")
    args = parser.parse_args(argv)
    config = {"tracker.kind": args.tracker}
    check_arguments(parser, [args.tier], [("predictive", config)])
    with tempfile.TemporaryDirectory(prefix="dynabarn-anatomy-") as scratch:
        folder = str(validation_worlds(args.tier, Path(scratch)))
        with ProcessPoolExecutor(args.jobs) as pool:
            rows = list(pool.map(episode, [(folder, w, config) for w in range(200, 200 + args.worlds)]))
    cells = Counter((kind, side, present) for _, present, kind, side in rows if kind != "-")
    others = Counter(side for _, _, kind, side in rows if kind == "-")
    print(f"{args.tier}, predictive ({args.tracker}), {len(rows)} worlds: {dict(others)} without a hit")
    for kind in KINDS:
        for side in SIDES:
            both, alone = cells[kind, side, "collision"], cells[kind, side, "success"]
            if both or alone:
                print(f"  {kind:<13} {side:<7} {both + alone:3d}  (oracle_present survived {alone})")
    if args.record:
        record = {
            "tier": args.tier,
            "seed": SEED,
            "worlds": [200, 200 + args.worlds - 1],
            "config": config,
            "episodes": [
                {"world": w, "oracle_present": present, "kind": kind, "side": side} for w, present, kind, side in rows
            ],
        }
        OUT.mkdir(parents=True, exist_ok=True)
        write_atomically(OUT / f"collisions_{args.tier}.json", json.dumps(record, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
