"""`dynabarn-train`: behaviour cloning and TD3 (the learn extra)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass
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


@dataclass
class _TD3Defaults:
    """`dynabarn.learn.td3.TD3Config`'s defaults, repeated here so `--help` works without
    PyTorch; a test checks the two agree."""

    world_set: str = "paper60"
    difficulty: str = "all"
    steps: int = 80_000
    envs: int = 1
    eval_every: int = 10_000
    eval_episodes: int = 30
    start_steps: int = 0
    update_every: int = 2
    demos: int = 200
    demo_share: float = 0.25
    bc_epochs: int = 30
    bc_lr: float = 1e-3
    critic_warmup: int = 2_000
    actor_start: int = 5_000
    bc_weight: float = 5.0
    bc_decay_steps: int = 100_000
    threads: int = 2
    seed: int = 0


TD3_DEFAULTS = _TD3Defaults()
TD3_OPTIONS = (
    ("steps", int, 1, 100_000_000, "environment steps in total"),
    ("envs", int, 1, MAX_JOBS, "parallel environments (one process each when > 1)"),
    ("eval_every", int, 1, 100_000_000, "steps between evaluations and checkpoints"),
    ("eval_episodes", int, 1, 10_000, "episodes per evaluation (training worlds, seeds of their own)"),
    ("start_steps", int, 0, 100_000_000, "uniformly random actions first"),
    ("update_every", int, 1, 1_000, "environment steps per gradient update"),
    ("demos", int, 0, 100_000, "oracle demonstration episodes in the replay buffer (0: none, the paper's TD3)"),
    ("demo_share", float, 0.0, 1.0, "share of every batch drawn from the demonstrations"),
    ("bc_epochs", int, 0, 10_000, "behaviour-cloning epochs on the demonstrations before TD3"),
    ("bc_lr", float, 1e-8, 1.0, "Adam learning rate of the behaviour cloning"),
    ("critic_warmup", int, 0, 1_000_000, "critic-only updates on the demonstrations before TD3"),
    ("actor_start", int, 0, 100_000_000, "steps of critic-only updates on the policy's own experience first"),
    ("bc_weight", float, 0.0, 100.0, "weight of the actor's distance to demonstrated actions (TD3+BC)"),
    ("bc_decay_steps", int, 1, 100_000_000, "steps over which bc_weight decays linearly to 0"),
    ("threads", int, 1, MAX_JOBS, "PyTorch threads (and demonstration processes)"),
    ("seed", int, 0, MAX_SEED, "seed of torch, the buffers and the environments"),
)


@dataclass
class _DaggerDefaults:
    """`dynabarn.learn.dagger.DaggerConfig`'s defaults (a test checks the two agree)."""

    iterations: int = 12
    episodes: int = 240
    max_steps: int = 400
    beta_decay: float = 0.5
    updates: int = 4000
    final_updates: int = 0
    batch_size: int = 512
    lr: float = 1e-3
    validation_episodes: int = 60
    history: int = 2
    history_every: int = 2
    tracks: int = 8
    workers: int = 2
    threads: int = 2
    seed: int = 0


DAGGER_DEFAULTS = _DaggerDefaults()
DAGGER_OPTIONS = (
    ("iterations", int, 1, 10_000, "DAgger iterations (collect, relabel, aggregate, fit, validate)"),
    ("episodes", int, 1, 1_000_000, "training episodes per iteration, each in a fresh procedural world"),
    ("max_steps", int, 10, 100_000, "steps after which a training episode is cut"),
    ("beta_decay", float, 0.0, 1.0, "the teacher drives with probability beta_decay ** iteration"),
    ("updates", int, 1, 100_000_000, "gradient steps per iteration over the whole aggregated dataset"),
    ("final_updates", int, 0, 100_000_000, "updates after the last iteration, the learning rate falling to 0"),
    ("batch_size", int, 1, 1_000_000, "rows per gradient step"),
    ("lr", float, 1e-8, 1.0, "Adam learning rate"),
    ("validation_episodes", int, 0, 100_000, "student-only episodes on validation worlds per iteration"),
    ("history", int, 0, 16, "earlier scans the student sees (0: the paper's single scan)"),
    ("history_every", int, 1, 50, "control ticks between history frames"),
    ("tracks", int, 0, 64, "nearest laser-tracker tracks the student sees (0: no tracker)"),
    ("workers", int, 1, MAX_JOBS, "collection processes"),
    ("threads", int, 1, MAX_JOBS, "PyTorch threads for fitting"),
    ("seed", int, 0, MAX_SEED, "seed of the split, the trials, the coin and torch"),
)


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-train`'s parser (its `--help`, and the documentation's page of the command)."""
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
        "td3",
        help="TD3 reinforcement learning (resumes from --out's last checkpoint when run again)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    td.add_argument("--set", default=TD3_DEFAULTS.world_set, help="world set to train in")
    td.add_argument("--difficulty", default=TD3_DEFAULTS.difficulty, help="easy, medium, hard or all")
    add_protocol(td)
    _add_options(td, TD3_OPTIONS, TD3_DEFAULTS)
    td.add_argument("--out", type=Path, required=True, help="folder for checkpoints, policy.pt and the learning curve")
    dg = sub.add_parser(
        "dagger",
        help="DAgger with the present-state oracle as teacher on procedural training worlds "
        "(resumes from --out's last iteration when run again)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_protocol(dg)
    _add_options(dg, DAGGER_OPTIONS, DAGGER_DEFAULTS)
    dg.add_argument(
        "--no-velocity", dest="velocity", action="store_false", help="leave the measured (v, w) out of the inputs"
    )
    dg.add_argument(
        "--profile-sets",
        default="table1,release2022",
        help="comma-separated profile sets the training worlds are drawn from",
    )
    dg.add_argument("--out", type=Path, required=True, help="folder for data, checkpoints, policy.pt and the curve")
    return parser


def _add_options(parser: argparse.ArgumentParser, options: tuple, defaults) -> None:
    """One `--name` per (name, type, low, high, help) row, checked against its range."""
    for name, kind, lo, hi, text in options:
        parser.add_argument(
            "--" + name.replace("_", "-"), type=ranged(kind, lo, hi), default=getattr(defaults, name), help=text
        )


def train_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
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
    if args.command == "dagger":
        return _train_dagger(args, tqdm)
    from dynabarn.learn.td3 import TD3Config, train_td3
    from dynabarn.worlds.profiles import Difficulty
    from dynabarn.worldset import world_set

    # Checked here, in one line: the environments that would find out run in worker processes.
    world_set(args.set)
    if args.difficulty not in ("all", *(d.value for d in Difficulty)):
        raise DynabarnError(f"--difficulty {args.difficulty!r}: use easy, medium, hard or all")
    cfg = TD3Config(
        world_set=args.set,
        difficulty=args.difficulty,
        protocol=args.protocol,
        **{name: getattr(args, name) for name, *_ in TD3_OPTIONS},
    )
    report = train_td3(
        cfg, args.out, progress=lambda total, initial=0: tqdm(total=total, initial=initial, desc="steps", disable=None)
    )
    last = report.evaluations[-1]
    print(
        f"wrote {args.out / 'policy.pt'} after {report.steps} steps ({report.episodes} episodes) in "
        f"{report.seconds:.0f} s; last evaluation: success {last['success']:.2f}, return {last['return']:.1f}; "
        f"curve: {args.out / 'learning_curve.png'}"
    )
    return 0


def _train_dagger(args: argparse.Namespace, tqdm) -> int:
    from dynabarn.learn.dagger import DaggerConfig, train_dagger
    from dynabarn.worlds.profiles import get_profile_set

    profile_sets = [p for p in args.profile_sets.split(",") if p]
    for name in profile_sets:
        get_profile_set(name)  # one line for an unknown name, before any worker starts
    cfg = DaggerConfig(
        protocol=args.protocol,
        velocity=args.velocity,
        profile_sets=profile_sets,
        **{name: getattr(args, name) for name, *_ in DAGGER_OPTIONS},
    )
    report = train_dagger(
        cfg, args.out, progress=lambda total, initial=0: tqdm(total=total, initial=initial, desc="iterations")
    )
    last = report.iterations[-1]
    validation = (report.final or last)["validation"]["success"]
    print(
        f"wrote {args.out / 'policy.pt'} after {len(report.iterations)} iterations ({last['dataset']} labelled "
        f"states, {len(set(report.fingerprints))} training worlds) in {report.seconds:.0f} s; validation success "
        f"{validation:.2f}{' after the final fit' if report.final else ''}; curve: {args.out / 'learning_curve.png'}"
    )
    return 0
