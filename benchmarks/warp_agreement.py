"""A fixed policy's success on the Warp backend against MuJoCo's C engine, over the same
episodes (world and trial): the Warp backend is float32 on another solver path, so its
episodes are not the C engine's bit for bit; what a learner needs is that a policy's
success agrees within its interval.

    python benchmarks/warp_agreement.py --set paper60 --envs 25 --per-env 4 --record

The policy (`pursuit`) reads only DynaBARN-v0's observation: it turns towards the local goal
and slows with the clearance ahead. The Warp side (`DynaBARNVectorEnv(backend="warp")` on
`--device`) runs `--envs` environments until each has finished its first `--per-env`
episodes (fixed in advance, so early endings are not favoured); the C side
(`DynaBARNEnv`) plays those same (world, trial) pairs. Both with the laser's noise, each
engine its own draw. `--record` writes results/warp_agreement/SET.json; the Warp page's
table (block `warp-agreement`) is generated from every record there.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from dynabarn.bench.stats import wilson_interval
from dynabarn.files import write_atomically

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "warp_agreement"
FRONT = slice(300, 421)
"""The beams within 30 degrees of straight ahead (0.375 degrees apart, 360 ahead)."""


def pursuit(obs: np.ndarray) -> np.ndarray:
    """(n, 722) observations -> (n, 2) actions: the heading to the local goal, and a speed
    that falls from full at 2.5 m of clearance ahead to none at 0.6 m."""
    heading = np.arctan2(obs[:, 721], obs[:, 720])
    clearance = obs[:, FRONT].min(axis=1)
    speed = np.clip((clearance - 0.6) / 1.9, 0.0, 1.0) * np.clip(1.0 - np.abs(heading) / 1.2, 0.0, 1.0)
    return np.stack([2.0 * speed - 1.0, np.clip(heading / 1.0, -1.0, 1.0)], axis=1).astype(np.float32)


def run_warp(set_name: str, envs: int, per_env: int, device: str, seed: int) -> tuple[list[dict], float]:
    import torch

    from dynabarn.learn.vector_env import DynaBARNVectorEnv

    env = DynaBARNVectorEnv(envs, backend="warp", device=device, world_set=set_name, seed=seed)
    obs, _ = env.reset()
    done = np.zeros(envs, dtype=int)
    episodes: list[dict] = []
    t0, periods = time.perf_counter(), 0
    while (done < per_env).any():
        actions = torch.from_numpy(pursuit(obs.cpu().numpy()))
        obs, _, terminated, truncated, info = env.step(actions.to(obs.device))
        periods += 1
        ended = (terminated | truncated).cpu().numpy()
        success = info["success"].cpu().numpy()
        for w in np.flatnonzero(ended):
            k = done[w]
            if k < per_env:
                outcome = "success" if success[w] else ("collision" if terminated[w] else "timeout")
                world = env.world_files[int(env.trial_worlds[w, k])]
                episodes.append({"env": int(w), "k": int(k), "world": world, "trial": int(env.trials[w, k])})
                episodes[-1]["warp"] = outcome
            done[w] += 1
        if periods % 50 == 0:
            print(
                f"  {periods} periods, {int(np.minimum(done, per_env).sum())} of {envs * per_env} episodes",
                file=sys.stderr,
            )
    return sorted(episodes, key=lambda e: (e["env"], e["k"])), time.perf_counter() - t0


def run_c(set_name: str, episodes: list[dict]) -> None:
    from dynabarn.learn.env import DynaBARNEnv

    env = DynaBARNEnv(world_set=set_name)
    index = {str(file): i for i, (_, file, _) in enumerate(env.entries)}
    for e in episodes:
        obs, _ = env.reset(options={"world_index": index[e["world"]], "trial_seed": e["trial"]})
        while True:
            obs, _, terminated, truncated, info = env.step(pursuit(obs[None])[0])
            if terminated or truncated:
                e["c"] = info["outcome"]
                break
    env.close()


def summary(record: dict) -> dict:
    eps = record["episodes"]
    n = len(eps)
    out = {"episodes": n, "same_outcome": sum(e["warp"] == e["c"] for e in eps)}
    for side in ("c", "warp"):
        wins = sum(e[side] == "success" for e in eps)
        lo, hi = wilson_interval(wins, n)
        out[side] = {"success": wins / n, "interval": [round(lo, 3), round(hi, 3)]}
    both = [(e["c"] == "success", e["warp"] == "success") for e in eps]
    out["c_only"] = sum(c and not w for c, w in both)
    out["warp_only"] = sum(w and not c for c, w in both)
    return out


def table(records: list[dict]) -> str:
    lines = [
        "| set | episodes | C engine: success [95% interval] | Warp backend (device) | same outcome "
        "| success on C only / on Warp only |",
        "|---|---|---|---|---|---|",
    ]
    for r in records:
        s = summary(r)
        c, w = s["c"], s["warp"]
        lines.append(
            f"| `{r['set']}` | {s['episodes']} | {c['success']:.2f} [{c['interval'][0]:.2f}, {c['interval'][1]:.2f}] "
            f"| {w['success']:.2f} [{w['interval'][0]:.2f}, {w['interval'][1]:.2f}] ({r['device']}) "
            f"| {s['same_outcome']} of {s['episodes']} | {s['c_only']} / {s['warp_only']} |"
        )
    return "\n".join(lines)


def read_records() -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(OUT.glob("*.json"))] if OUT.is_dir() else []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--set", default="paper60", help="the world set (default: paper60)")
    parser.add_argument("--envs", type=int, default=25, help="Warp environments (default: 25)")
    parser.add_argument("--per-env", type=int, default=4, help="episodes counted per environment (default: 4)")
    parser.add_argument("--device", default="cpu", help="Warp device: cpu, cuda, cuda:N (default: cpu)")
    parser.add_argument("--seed", type=int, default=0, help="draws the environments' worlds and trials (default: 0)")
    parser.add_argument("--record", action="store_true", help="write results/warp_agreement/SET.json")
    args = parser.parse_args(argv)
    episodes, seconds = run_warp(args.set, args.envs, args.per_env, args.device, args.seed)
    print(f"Warp: {len(episodes)} episodes in {seconds:.0f} s; the C engine ...", file=sys.stderr)
    run_c(args.set, episodes)
    for e in episodes:
        e["world"] = Path(e["world"]).name  # the record names files within the set, not this machine's folders
    record = {"set": args.set, "device": args.device, "seed": args.seed, "envs": args.envs, "episodes": episodes}
    record["policy"] = (
        "pursuit: heading to the local goal, speed from the clearance ahead (benchmarks/warp_agreement.py)"
    )
    print(table([record]))
    if args.record:
        OUT.mkdir(parents=True, exist_ok=True)
        write_atomically(OUT / f"{args.set}.json", json.dumps(record, indent=1, sort_keys=True) + "\n")
    return 0 if math.isfinite(seconds) else 1


if __name__ == "__main__":
    sys.exit(main())
