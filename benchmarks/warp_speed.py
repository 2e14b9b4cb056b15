"""Control steps per second of the Warp backend (`WarpVectorEnv`, every world's full 722-value
observation) against the number of worlds, with where the time goes, and the C engine's
vector environment on the same machine in the same run.

    python benchmarks/warp_speed.py --device cpu --envs 1,8,32 --record       # here: Warp's CPU device
    python benchmarks/warp_speed.py --device cuda --envs 1,16,256,4096,16384 --record   # on a GPU
    python benchmarks/warp_speed.py --device cuda --set tier-combined --envs 4096 --record   # a set's batch

`--record` writes results/warp_speed/DEVICE.json (`cpu-device`, or the GPU's name); the
speed page's table (block `warp-speed`) is generated from every record there. Shares:
physics (the 20 steps of a period with the obstacles placed and the protocol's checks),
scan (kinematics and the 720 rangefinders), schedules (the obstacles' placement alone,
part of physics), the environment's own kernels (rewards, autoreset, local goals: the rest
of a period); the policy: a forward pass of a 722-512-512-2 MLP over the batch on the same
device. Warp's CPU device is for correctness: its figures say nothing of a GPU's.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from dynabarn.files import write_atomically

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "warp_speed"
WORLD = ROOT / "generated_worlds" / "world_137.xml"


def _timed(fn, periods: int, sync) -> float:
    """Seconds per call of fn over `periods` calls, the device synchronised around them."""
    sync()
    t0 = time.perf_counter()
    for _ in range(periods):
        fn()
    sync()
    return (time.perf_counter() - t0) / periods


def measure_warp(device: str, n: int, periods: int, world_set: str | None = None) -> dict:
    import torch
    import warp as wp

    from dynabarn.learn.vector_env import DynaBARNVectorEnv
    from dynabarn.learn.warp_env import WarpVectorEnv

    if world_set is None:
        env = WarpVectorEnv(str(WORLD), n, device=device, seed=0)
    else:  # every world of the set in one padded batch, each environment drawing its own
        env = DynaBARNVectorEnv(n, backend="warp", device=device, world_set=world_set, seed=0)
    env.reset()
    torch_device = "cpu" if device == "cpu" else device
    actions = torch.rand((n, 2), device=torch_device) * 2 - 1
    for _ in range(2):  # the kernels compiled and loaded
        env.step(actions)

    def sync() -> None:
        wp.synchronize_device(device)

    worlds = env.worlds
    total = _timed(lambda: env.step(actions), periods, sync)
    physics = _timed(lambda: worlds.step(env._commands, observe=False), periods, sync)
    scan = _timed(worlds.observe, periods, sync)
    with wp.ScopedDevice(device):
        schedules = _timed(lambda: [worlds._place() for _ in range(worlds.k)], periods, sync)
    policy = torch.nn.Sequential(
        torch.nn.Linear(722, 512), torch.nn.ReLU(), torch.nn.Linear(512, 512), torch.nn.ReLU(), torch.nn.Linear(512, 2)
    ).to(torch_device)
    obs = wp.to_torch(env.obs)
    with torch.no_grad():
        forward = _timed(lambda: policy(obs), periods, sync)
    return {
        "worlds": n,
        "steps_per_s": round(n / total, 1),
        "ms_per_period": round(total * 1e3, 3),
        "physics_share": round(physics / total, 3),
        "scan_share": round(scan / total, 3),
        "schedule_share": round(schedules / total, 3),
        "env_share": round(max(0.0, 1 - (physics + scan) / total), 3),
        "policy_ms": round(forward * 1e3, 3),
    }


def measure_c(n: int, periods: int, world_set: str | None = None) -> dict:
    """The C engine's vector environment on world 137, or on the set's worlds (every core of
    this machine)."""
    from dynabarn.learn.vector_env import DynaBARNVectorEnv

    where = {"world_set": "paper60", "worlds": [137]} if world_set is None else {"world_set": world_set}
    vec = DynaBARNVectorEnv(n, **where)
    try:
        vec.reset(seed=0)
        rng = np.random.default_rng(0)
        for _ in range(5):
            vec.step(rng.uniform(-1, 1, (n, 2)).astype(np.float32))
        t0 = time.perf_counter()
        for _ in range(periods):
            vec.step(rng.uniform(-1, 1, (n, 2)).astype(np.float32))
        seconds = time.perf_counter() - t0
    finally:
        vec.close()
    return {"worlds": n, "workers": vec.workers, "steps_per_s": round(n * periods / seconds, 1)}


def device_name(device: str) -> str:
    if device == "cpu":
        return "cpu-device"
    import warp as wp

    return wp.get_device(device).name.replace(" ", "-")


def table(records: list[dict]) -> str:
    """The speed page's table: per record and batch size, steps/s and where a period goes."""
    lines = [
        "| device (machine) | worlds (of) | control steps/s | ms per period | physics | scan | of which schedules "
        "| environment | policy forward, ms | C engine's vector env, steps/s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for record in records:
        c = record["c_engine"]
        for row in record["warp"]:
            lines.append(
                f"| {record['device']} ({record['machine']}) | {row['worlds']:,} ({_of(record)}) | "
                f"{row['steps_per_s']:,.0f} | "
                f"{row['ms_per_period']:.1f} | {row['physics_share']:.0%} | {row['scan_share']:.0%} | "
                f"{row['schedule_share']:.0%} | {row['env_share']:.0%} | {row['policy_ms']:.2f} | "
                f"{c['steps_per_s']:,.0f} ({c['worlds']} worlds, {c['workers']} workers) |"
            )
    return "\n".join(lines)


def _of(record: dict) -> str:
    world = record.get("world", 137)
    return f"world {world}" if isinstance(world, int) else f"`{world}`"


def read_records() -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(OUT.glob("*.json"))] if OUT.is_dir() else []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cpu", help="Warp device: cpu, cuda, cuda:N (default: cpu)")
    parser.add_argument("--envs", default="1,8,32", help="batch sizes, comma-separated (default: 1,8,32)")
    parser.add_argument("--periods", type=int, default=10, help="control periods timed per size (default: 10)")
    parser.add_argument("--c-envs", type=int, default=64, help="worlds of the C engine's vector env (default: 64)")
    parser.add_argument(
        "--set", default=None, help="a world set's worlds in one batch (default: world 137 alone); recorded apart"
    )
    parser.add_argument("--record", action="store_true", help="write results/warp_speed/DEVICE[-SET].json")
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.envs.split(",")]
    rows = []
    for n in sizes:
        print(f"{n} worlds on {args.device} ...", file=sys.stderr, flush=True)
        rows.append(measure_warp(args.device, n, args.periods, args.set))
    print(f"the C engine's vector env, {args.c_envs} worlds ...", file=sys.stderr, flush=True)
    record = {
        "device": device_name(args.device),
        "machine": f"{os.cpu_count()} cores",
        "world": 137 if args.set is None else args.set,
        "periods": args.periods,
        "warp": rows,
        "c_engine": measure_c(args.c_envs, max(args.periods, 20), args.set),
    }
    print(table([record]))
    if args.record:
        OUT.mkdir(parents=True, exist_ok=True)
        name = record["device"] + ("" if args.set is None else f"-{Path(args.set).name}")
        write_atomically(OUT / f"{name}.json", json.dumps(record, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
