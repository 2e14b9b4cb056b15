"""Why real move_base's DWA beat ours: each difference between the two, taken one at a time.

Real move_base (the DynaBARN authors' configuration, `--stack move_base_dwa`) and our
planners on `paper60`, 5 trials per world, lockstep; and the real stack run again (2
trials): it is not deterministic, so its agreement with itself is what ours can reach. Each variant is our `dwa` or
`trajectory_planner` with the preset `dwa_dynabarn_authors` and a few parameters changed.
The outcome of every episode lands in `results/move_base_dwa_ablation/outcomes.csv`
(variant, world, seed, difficulty, outcome, time), which `ros_tables.py` turns into the
table of docs/tutorials/ros.md beside the real stack's rows of `results/move_base_paper60`.

    python benchmarks/dwa_ablation.py --work /tmp/dwa_ablation   # resumable; ~5 min a variant on 2 cores

The sweeps themselves go to --work (one `dynabarn-bench` folder per variant); only the
outcomes are committed.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "move_base_dwa_ablation" / "outcomes.csv"
FIELDS = ("variant", "world", "seed", "difficulty", "outcome", "time")
BEFORE_FIX = {"path_distance_bias": 0.075, "goal_distance_bias": 0.1, "lookahead": 3.0}
"""The preset as it was translated before: the biases per 0.1 m cell on a 0.05 m costmap
(twice ROS's per-metre weights) and the local goal 3 m ahead (ROS: the plan's end inside
the 10 m local costmap, 5 m)."""

VARIANTS: dict[str, tuple[str, dict, str]] = {
    "real_again": ("ros", {}, "real move_base again, 2 trials (how often it repeats itself)"),
    "dwa_before_fix": ("dwa", BEFORE_FIX, "`dwa`, the preset as first translated (biases x2, local goal 3 m)"),
    "dwa_biases_fixed": ("dwa", {"lookahead": 3.0}, "`dwa`, biases per 0.05 m cell only (local goal 3 m)"),
    "dwa_goal_fixed": (
        "dwa",
        {"path_distance_bias": 0.075, "goal_distance_bias": 0.1},
        "`dwa`, local goal 5 m only (biases x2)",
    ),
    "dwa": ("dwa", {}, "`dwa@dwa_dynabarn_authors` (both fixed)"),
    "tp": ("trajectory_planner", {}, "`trajectory_planner@dwa_dynabarn_authors` (all of TrajectoryPlanner's ways)"),
    "tp_no_rotate_in_place": ("trajectory_planner", {"rotate_in_place": False}, "... without stopping to turn"),
    "tp_no_ramp": ("trajectory_planner", {"ramp": False}, "... with constant-velocity rollouts"),
    "tp_no_score_at_end": ("trajectory_planner", {"score_at_end": False}, "... scoring a point ahead (as `dwa`)"),
    "tp_no_ros_escape": ("trajectory_planner", {"ros_escape": False}, "... with `dwa`'s escape"),
    "tp_no_slow_near_goal": ("trajectory_planner", {"slow_near_goal": False}, "... not slowing near the goal"),
    "tp_no_sim_period": ("trajectory_planner", {"sim_period": 0.0}, "... its window over the 0.1 s control period"),
    "tp_before_fix": ("trajectory_planner", BEFORE_FIX, "... with the preset as first translated"),
}
"""id -> (planner, parameters over the preset, what the table calls it)."""


def sweep(variant: str, work: Path) -> Path:
    """Run (or resume) one variant's sweep; its results.jsonl."""
    from dynabarn.cli.bench import bench_main

    planner, overrides, _ = VARIANTS[variant]
    out = work / variant
    if planner == "ros":  # the real stack a second time (seeds 0 and 1): what agreement can reach
        argv = ["--planner", "ros", "--ros-stack", "move_base_dwa", "--trials", "2"]
    else:
        config = work / f"{variant}.json"
        config.write_text(json.dumps({"_extends": "dwa_dynabarn_authors", **overrides}))
        argv = ["--planner", planner, "--planner-config", str(config), "--trials", "5"]
    argv += ["--no-floor", "--set", "paper60", "--jobs", str(os.cpu_count() or 1)]
    if bench_main([*argv, "--out", str(out)]) != 0:
        raise SystemExit(f"the sweep of {variant} failed (see above)")
    return out / "results.jsonl"


def outcomes(variant: str, results: Path) -> list[dict]:
    rows = [json.loads(line) for line in results.read_text().splitlines() if line.strip()]
    if len({(r["world"], r["seed"]) for r in rows}) != len(rows):
        raise SystemExit(f"{results} holds an episode twice (two configurations in one folder?)")
    return [
        {
            "variant": variant,
            "world": r["world"],
            "seed": r["seed"],
            "difficulty": r["difficulty"],
            "outcome": r["outcome"],
            "time": f"{r['time']:.3f}",
        }
        for r in rows
    ]


def read_outcomes(path: Path = OUT) -> list[dict]:
    """The committed outcomes (empty when the file is absent)."""
    if not path.is_file():
        return []
    with path.open(newline="") as f:
        return [dict(row, seed=int(row["seed"])) for row in csv.DictReader(f)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True, help="folder of the variants' sweeps (resumable)")
    parser.add_argument("--only", default="", help="comma-separated variant ids (default: all)")
    args = parser.parse_args(argv)
    chosen = [v for v in args.only.split(",") if v] or list(VARIANTS)
    unknown = sorted(set(chosen) - set(VARIANTS))
    if unknown:
        parser.error(f"unknown variants {unknown}; choose from {', '.join(VARIANTS)}")
    args.work.mkdir(parents=True, exist_ok=True)
    kept = [row for row in read_outcomes() if row["variant"] not in chosen]
    rows = kept + [row for v in chosen for row in outcomes(v, sweep(v, args.work))]
    rows.sort(key=lambda r: (list(VARIANTS).index(r["variant"]), r["world"], r["seed"]))
    OUT.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=OUT.parent, delete=False, newline="") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        f.flush()
        os.fsync(f.fileno())
    os.replace(f.name, OUT)
    print(f"wrote {len(rows)} outcomes of {len({r['variant'] for r in rows})} variants to {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
