"""The trackers on validation worlds (issue 57): what every change to a tracker was measured
on, never the evaluation sets.

Validation worlds: each tier's shipped profile drawn under another base seed (5700), written
to a scratch folder; the hard worlds (the first `--worlds` of ids 200-219), one trial. The
robot's path is fixed: `oracle_present` drives and each tracker watches the same scans (an
episode observer would see the same; here a planner that wraps `oracle_present` and runs the
tracker beside it), so two trackers are compared on the same views. Scored by the runner's
own `sim/track_scoring.py`, per episode; reported as the medians over episodes, as the
sweeps' tables report them.

Beside the table, the error of every matched pair against the obstacle's range and speed
(an episode observer sees the ticks' true obstacles and the tracks), drawn per tracker in
docs/assets/tracking_error.png.

`python benchmarks/tracker_validation.py` writes results/tracker_validation/validation.json,
the figure, and prints the table (about 5 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.files import write_atomically
from dynabarn.interfaces import EpisodeObserver, Planner
from dynabarn.perception.trackers import make_tracker
from dynabarn.planners import get_planner
from dynabarn.planners.tracking import with_tracker
from dynabarn.protocol import get_protocol
from dynabarn.runner import EpisodeSpec, run_spec
from dynabarn.sim.track_scoring import matched_pairs
from dynabarn.worlds.tiers import PROFILES_DIR, TIERS

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "tracker_validation" / "validation.json"
FIGURE = ROOT / "docs" / "assets" / "tracking_error.png"
RANGE_BINS = np.array([0.0, 2.0, 4.0, 6.0, 8.0, 12.0, 30.0])
SPEED_BINS = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 4.0])
SEED = 5700
TRACKER_KINDS = ("kalman", "shaped", "registered")
FIELDS = (
    "recall",
    "precision",
    "position_error_median",
    "position_error_p95",
    "velocity_error_p95",
    "id_switches",
    "id_switches_mot",
)


class Watching(Planner):
    """`oracle_present` drives; a tracker of `kind` watches every scan and reports its tracks."""

    name = "watching"
    privileged = True

    def __init__(self, kind: str) -> None:
        self.driver = get_planner("oracle_present")
        self.tracker_config = with_tracker({"tracker.kind": kind}, "watching")["tracker"]
        self._tracks = None

    def reset(self, info) -> None:
        self.driver.reset(info)
        self.tracker = make_tracker(self.tracker_config, info)
        self._tracks = None

    def act(self, obs):
        self._tracks = self.tracker.update(obs.time, obs.scan, obs.pose)
        return self.driver.act(obs)

    def tracks(self):
        return self._tracks


class PairErrors(EpisodeObserver):
    """Every tick: tracks matched one to one with the true centres within 1 m (as the
    scoring matches them); (range [m], speed [m/s], position error [m], 1 for a box or a
    capsule and 0 for a cylinder) of each pair."""

    def __init__(self) -> None:
        self.pairs: list[tuple[float, float, float, float]] = []
        self._last = None

    def on_start(self, start) -> None:
        self._last = None
        self.shaped = np.array([o.shape != "cylinder" for o in start.world.obstacles], dtype=float)

    def on_tick(self, tick) -> None:
        truth, tracks = np.asarray(tick.obstacles), tick.tracks
        speed = np.zeros(len(truth)) if self._last is None else np.hypot(*((truth - self._last) / 0.1).T)
        self._last = truth.copy()
        if tracks is None or not len(tracks) or not len(truth):
            return
        rows, cols, d = matched_pairs(tracks.positions, truth)
        reach = np.hypot(*(truth[cols] - tick.pose[:2]).T)
        columns = (reach, speed[cols], d[rows, cols], self.shaped[cols])
        self.pairs += list(zip(*(c.tolist() for c in columns), strict=True))

    def on_poses(self, times, poses) -> None:
        pass

    def on_end(self, result) -> None:
        pass


def check_arguments(parser: argparse.ArgumentParser, tiers: list[str], planners: list[tuple[str, dict]]) -> None:
    """Before anything runs: each of `tiers` a tier and each (planner, configuration) one
    the planner accepts, or the parser's one-line error (exit 2)."""
    unknown = sorted(set(tiers) - set(TIERS))
    if unknown:
        parser.error(f"unknown tier(s) {unknown}; known: {', '.join(TIERS)}")
    for name, config in planners:
        try:
            get_planner(name, **config)
        except DynabarnError as exc:
            parser.error(str(exc))


def validation_worlds(tier: str, folder: Path) -> Path:
    """The tier's profile under the validation seed, written once into `folder`."""
    from dynabarn.cli.worlds import worlds_main

    out = folder / tier
    if not (out / "index.json").is_file():
        profile = PROFILES_DIR / TIERS[tier].profile_file
        worlds_main(["generate", "--profile-file", str(profile), "--seed", str(SEED), "--out", str(out)])
    return out


def measure(folder: Path, kind: str, n_worlds: int, pairs: list) -> dict:
    rows = []
    for world_id in range(200, 200 + n_worlds):
        errors = PairErrors()
        world = folder / f"world_{world_id:03d}.xml"
        watching = Watching(kind)
        spec = EpisodeSpec.make(world, watching.name, get_protocol("barn"), seed=0)
        result = run_spec(spec, planner=watching, observers=[errors]).result
        rows.append(result.tracking)
        pairs += errors.pairs
    medians = {key: float(np.median([r[key] for r in rows if r.get(key) is not None])) for key in FIELDS}
    return medians | {"episodes": len(rows)}


def binned(values: np.ndarray, errors: np.ndarray, bins: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Median and 95th percentile of `errors` in each bin of `values` (nan where empty)."""
    which = np.digitize(values, bins) - 1
    med = np.array([np.median(errors[which == b]) if (which == b).any() else np.nan for b in range(len(bins) - 1)])
    p95 = np.array(
        [np.percentile(errors[which == b], 95) if (which == b).any() else np.nan for b in range(len(bins) - 1)]
    )
    return med, p95


def draw(pairs: dict[str, np.ndarray]) -> None:
    """Position error against range and against speed, per tracker, for cylinders and for
    boxes and capsules (all tiers' pairs)."""
    from matplotlib.figure import Figure

    from dynabarn.files import save_atomically

    fig = Figure(figsize=(9.0, 6.4), dpi=110)
    axes = fig.subplots(2, 2, sharey=True)
    for row, (shaped, what) in enumerate(((0.0, "cylinders"), (1.0, "boxes and capsules"))):
        for ax, column, bins, label in (
            (axes[row, 0], 0, RANGE_BINS, "range [m]"),
            (axes[row, 1], 1, SPEED_BINS, "speed [m/s]"),
        ):
            middle = 0.5 * (bins[:-1] + bins[1:])
            for kind, colour in zip(TRACKER_KINDS, ("tab:blue", "tab:orange", "tab:green"), strict=True):
                p = pairs[kind][pairs[kind][:, 3] == shaped]
                med, p95 = binned(p[:, column], p[:, 2], bins)
                ax.plot(middle, 1000 * med, "o-", color=colour, label=f"{kind}: median")
                ax.plot(middle, 1000 * p95, "s--", color=colour, alpha=0.6, label=f"{kind}: 95th percentile")
            ax.set_xlabel(f"obstacle {label}")
            ax.set_yscale("log")
            ax.grid(alpha=0.3)
            ax.set_title(what, fontsize=9)
        axes[row, 0].set_ylabel("position error [mm]")
    axes[0, 1].legend(fontsize=7)
    title = f"Trackers on validation worlds of every tier (seed {SEED}, hard, the robot's path fixed)"
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_atomically(FIGURE, lambda f: fig.savefig(f, format="png"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", type=int, default=8, help="hard worlds per tier (default: 8)")
    args = parser.parse_args(argv)
    table: dict[str, dict] = {}
    pairs: dict[str, list] = {kind: [] for kind in TRACKER_KINDS}
    with tempfile.TemporaryDirectory(prefix="dynabarn-validation-") as scratch:
        for tier in TIERS:
            folder = validation_worlds(tier, Path(scratch))
            table[tier] = {kind: measure(folder, kind, args.worlds, pairs[kind]) for kind in TRACKER_KINDS}
            for kind, m in table[tier].items():
                print(
                    f"{tier:<14} {kind:<7} recall {m['recall']:.3f} precision {m['precision']:.3f} "
                    f"position {1000 * m['position_error_median']:.1f} / {1000 * m['position_error_p95']:.0f} mm "
                    f"velocity p95 {m['velocity_error_p95']:.2f} m/s switches {m['id_switches']:.1f} "
                    f"(CLEAR-MOT {m['id_switches_mot']:.1f})",
                    flush=True,
                )
    record = {"seed": SEED, "worlds_per_tier": args.worlds, "driver": "oracle_present", "tiers": table}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(OUT, json.dumps(record, indent=1, sort_keys=True) + "\n")
    draw({kind: np.array(p).reshape(-1, 4) for kind, p in pairs.items()})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
