"""`dynabarn-train`: behaviour cloning and TD3 (the learn extra)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    MAX_JOBS,
    MAX_SEED,
    add_protocol,
    make_parser,
    ranged,
    run_command,
    subcommands,
)
from dynabarn.errors import LEARN_EXTRA, DynabarnError


def train_main(argv: Sequence[str] | None = None) -> int:
    parser = make_parser(
        "dynabarn-train",
        f"Train the learned baselines (needs {LEARN_EXTRA}).",
    )
    sub = subcommands(parser)
    bc = sub.add_parser(
        "bc", help="behaviour cloning from a dataset", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    bc.add_argument("--data", type=Path, required=True, help="dataset from `dynabarn-demos export`")
    bc.add_argument("--out", type=Path, required=True, help="policy file to write (.pt)")
    bc.add_argument("--epochs", type=ranged(int, 1, 100_000), default=30, help="passes over the data")
    bc.add_argument("--batch-size", type=ranged(int, 1, 1_000_000), default=256, help="rows per gradient step")
    bc.add_argument("--lr", type=ranged(float, 1e-8, 1.0), default=1e-3, help="Adam learning rate")
    bc.add_argument("--seed", type=ranged(int, 0, MAX_SEED), default=0, help="torch seed")
    td = sub.add_parser(
        "td3", help="TD3 reinforcement learning", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    td.add_argument("--set", default="paper60", help="world set to train in")
    td.add_argument("--difficulty", default="easy", help="easy, medium, hard or all")
    add_protocol(td)
    td.add_argument("--steps", type=ranged(int, 1, 100_000_000), default=20_000, help="environment steps in total")
    td.add_argument(
        "--envs", type=ranged(int, 1, MAX_JOBS), default=1, help="parallel environments (one process each when > 1)"
    )
    td.add_argument(
        "--eval-every",
        type=ranged(int, 1, 100_000_000),
        default=5_000,
        help="steps between evaluations and checkpoints",
    )
    td.add_argument("--eval-episodes", type=ranged(int, 1, 10_000), default=10, help="episodes per evaluation")
    td.add_argument(
        "--start-steps", type=ranged(int, 0, 100_000_000), default=2_000, help="uniformly random actions first"
    )
    td.add_argument(
        "--seed", type=ranged(int, 0, MAX_SEED), default=0, help="seed of torch, the buffer and the environments"
    )
    td.add_argument("--out", type=Path, required=True, help="folder for checkpoints, policy.pt and the learning curve")
    args = parser.parse_args(argv)
    return run_command(_train, args)


def _train(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    try:
        import torch  # noqa: F401
    except ImportError:
        raise DynabarnError(f"dynabarn-train needs {LEARN_EXTRA}") from None
    if args.command == "bc":
        from dynabarn.learn.bc import train_bc

        report = train_bc(
            args.data,
            args.out,
            epochs=args.epochs,
            batch_size=args.batch_size,
            lr=args.lr,
            seed=args.seed,
            progress=lambda it: tqdm(it, desc="epochs", disable=None, leave=False),
        )
        print(
            f"wrote {args.out}: {report.rows} rows, {report.epochs} epochs in {report.seconds:.1f} s, "
            f"loss {report.losses[0]:.4f} -> {report.losses[-1]:.4f}"
        )
        return 0
    from dynabarn.learn.td3 import TD3Config, train_td3

    cfg = TD3Config(
        steps=args.steps,
        envs=args.envs,
        world_set=args.set,
        difficulty=args.difficulty,
        protocol=args.protocol,
        eval_every=args.eval_every,
        eval_episodes=args.eval_episodes,
        start_steps=args.start_steps,
        seed=args.seed,
    )
    if cfg.steps < 1 or cfg.envs < 1:
        raise DynabarnError("--steps and --envs must be positive")
    report = train_td3(cfg, args.out, progress=lambda total: tqdm(total=total, desc="steps", disable=None))
    last = report.evaluations[-1]
    print(
        f"wrote {args.out / 'policy.pt'} after {report.steps} steps ({report.episodes} episodes) in "
        f"{report.seconds:.0f} s; last evaluation: success {last['success']:.2f}, return {last['return']:.1f}; "
        f"curve: {args.out / 'learning_curve.png'}"
    )
    return 0
