"""What a ROS stack in lockstep costs: each real stack built here drives world 137 through
`dynabarn-ros` (a fresh process per stack, as a user runs it), and the episode's wall time,
times real time, the stack's time to answer a control period and the bridge's own time per
period are recorded.

`python benchmarks/ros_speed.py --record` writes results/ros_speed/world137.json (a few
minutes on 2 cores; stacks not built here are left out and named); its table is generated
on docs/speed.md (block `ros-speed`). Beside each stack, `dwa` through `dynabarn-run`: the
same world without ROS.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dynabarn.files import write_atomically

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "ros_speed" / "world137.json"
BIN = Path(sys.executable).parent
STACKS = ("move_base_dwa", "nav2_dwb", "nav2_mppi")
"""The real stacks timed (each where it is built)."""


def run_stack(stack: str | None, folder: Path) -> dict:
    """One episode of world 137: with `stack` through dynabarn-ros, or `dwa` through
    dynabarn-run (None); the result document, its wall time, or why it could not run."""
    recording = folder / f"{stack or 'dwa'}.mcap"
    if stack is None:
        cmd = [str(BIN / "dynabarn-run"), "--world", "137", "--planner", "dwa", "--log", str(recording), "--json"]
    else:
        cmd = [str(BIN / "dynabarn-ros"), "--world", "137", "--stack", stack, "--log", str(recording), "--json"]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=900, env={**os.environ, "PYTHONSAFEPATH": "1"})
    wall = time.perf_counter() - t0
    if done.returncode == 2:  # not built here (one line), or a bad setting
        return {"skipped": done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "exit 2"}
    result = json.loads(done.stdout)
    return {
        "outcome": result["outcome"],
        "sim_time": result["sim_time"],
        "n_ticks": result["n_ticks"],
        "command_seconds": round(wall, 2),
        "rtf": result["rtf"],
        "stack_ms_per_period": result["planner_ms_mean"],
        "bridge_ms_per_period": result.get("bridge_ms_per_tick"),
        "held_periods": result.get("held_periods"),
    }


def table(record: dict | None) -> str:
    """The speed page's table: per stack, its outcome, x real time over the episode, the
    stack's answer and the bridge's own time per control period, the command's wall time."""
    lines = [
        "| stack | ROS | outcome | simulated s | x real time | stack's answer, ms per period | bridge, ms per period "
        "| periods held | command, wall s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    if record is None:
        return "\n".join(lines)
    for name, r in record["runs"].items():
        if "skipped" in r:
            lines.append(f"| `{name}` | - | not built here: {r['skipped']} | | | | | | |")
            continue
        ros = "-" if name == "dwa" else ("2" if name.startswith("nav2") else "1")
        bridge = "-" if r["bridge_ms_per_period"] is None else f"{r['bridge_ms_per_period']:.2f}"
        held = "-" if r["held_periods"] is None else r["held_periods"]
        lines.append(
            f"| `{name}` | {ros} | {r['outcome']} | {r['sim_time']:.1f} | {r['rtf']:.1f} | "
            f"{r['stack_ms_per_period']:.1f} | {bridge} | {held} | {r['command_seconds']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--record", action="store_true", help=f"write {OUT.relative_to(ROOT)} (default: print only)")
    args = parser.parse_args(argv)
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for stack in (None, *STACKS):
            name = stack or "dwa"
            print(f"world 137 with {name} ...", file=sys.stderr, flush=True)
            runs[name] = run_stack(stack, Path(tmp))
    record = {"world": 137, "machine": f"{os.cpu_count()} cores", "runs": runs}
    print(table(record))
    if args.record:
        OUT.parent.mkdir(parents=True, exist_ok=True)
        write_atomically(OUT, json.dumps(record, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
