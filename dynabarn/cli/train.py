"""`dynabarn-train`: behaviour cloning and TD3 (the learn extra)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    MAX_SEED,
    add_protocol,
    add_renamed,
    command,
    make_parser,
    ranged,
    run_command,
    subcommands,
)
from dynabarn.errors import LEARN_EXTRA, DynabarnError


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-train`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-train",
        f"Train the learned baselines (needs {LEARN_EXTRA}).",
    )
    # After make_parser has chosen MuJoCo's OpenGL platform (Gymnasium's registration loads
    # MuJoCo); no PyTorch: --help works without the extra.
    from dynabarn.learn.configs import TD3Config

    sub = subcommands(parser)
    bc = sub.add_parser(
        "bc", help="behaviour cloning from a dataset", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    bc.add_argument("--data", type=Path, required=True, help="dataset from `dynabarn-demos export`")
    bc.add_argument("--out", type=Path, required=True, help="folder for policy.pt (as td3 and dagger)")
    bc.add_argument("--epochs", type=ranged(int, 1, 100_000), default=30, help="passes over the data")
    bc.add_argument("--batch-size", type=ranged(int, 1, 1_000_000), default=256, help="rows per gradient step")
    bc.add_argument("--lr", type=ranged(float, 1e-8, 1.0), default=1e-3, help="Adam learning rate")
    bc.add_argument("--seed", type=ranged(int, 0, MAX_SEED), default=0, help="torch seed")
    td = sub.add_parser(
        "td3",
        help="TD3 reinforcement learning (resumes from --out's last checkpoint when run again)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    td.add_argument("--set", default=TD3Config.world_set, help="world set to train in")
    td.add_argument("--difficulty", default=TD3Config.difficulty, help="easy, medium, hard or all")
    add_protocol(td)
    _add_options(td, TD3Config)
    td.add_argument("--out", type=Path, required=True, help="folder for checkpoints, policy.pt and the learning curve")
    _add_dagger(sub)
    _add_ppo(sub)
    return parser


def _add_ppo(sub) -> None:
    """`dynabarn-train ppo`: PPO on the Warp backend (`learn.ppo`)."""
    from dynabarn.learn.configs import PPOConfig

    pp = sub.add_parser(
        "ppo",
        help="PPO on the Warp backend: thousands of episodes at once on a GPU (the gpu extra; "
        "resumes from --out's checkpoint when run again)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    where = pp.add_mutually_exclusive_group()
    where.add_argument(
        "--world", default=None, help="one world trained in: an id of the 300, or a world file (the default: 137)"
    )
    where.add_argument(
        "--split",
        choices=("train", "validation"),
        default=None,
        help="procedural worlds of a split (never the evaluation sets'): its first --procedural-worlds, drawn "
        "from --split-seed",
    )
    where.add_argument(
        "--world-set", default=None, help="every world of a set or folder (with --difficulty: those of one)"
    )
    pp.add_argument("--difficulty", choices=("easy", "medium", "hard"), default=None, help="with --world-set")
    pp.add_argument("--split-seed", type=int, default=0, help="with --split: which procedural worlds")
    pp.add_argument("--procedural-worlds", type=int, default=64, help="with --split: how many worlds the batch holds")
    pp.add_argument(
        "--env-backend",
        choices=("warp",),
        default="warp",
        help="where the worlds are stepped: warp (MuJoCo Warp on --device); the C engine's vector environment "
        "takes Stable-Baselines3's PPO as any Gymnasium environment does",
    )
    pp.add_argument(
        "--device",
        default="auto",
        help="Warp and PyTorch device: cuda, cuda:N, cpu (Warp's CPU device: for checking, slow), or auto (cuda "
        "when Warp sees one)",
    )
    _add_options(pp, PPOConfig)
    pp.add_argument("--out", type=Path, required=True, help="folder for policy.pt, checkpoint.pt and history.json")


def _add_dagger(sub) -> None:
    """`dynabarn-train dagger`'s options: the configuration's fields, then the choices."""
    from dynabarn.learn.configs import DEVICES, ENV_BACKENDS, SHIPPED_STUDENT_PROFILE_SETS, TEACHERS, DaggerConfig
    from dynabarn.planners.learned.spaces import ENCODERS, HEADS

    dg = sub.add_parser(
        "dagger",
        help="DAgger with a search planner as teacher on procedural training worlds "
        "(resumes from --out's last iteration when run again)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_protocol(dg)
    _add_options(dg, DaggerConfig)
    dg.add_argument(
        "--teacher",
        choices=TEACHERS,
        default=DaggerConfig.teacher,
        help="who labels every state: the oracle told the obstacles' true present state (privileged), or "
        "predictive, the same search on the laser tracker's predictions (what the student sees)",
    )
    dg.add_argument(
        "--head",
        choices=HEADS,
        default=DaggerConfig.head,
        help="the student's output: regress the teacher's action, or classify among its candidate commands",
    )
    dg.add_argument(
        "--encoder",
        choices=ENCODERS,
        default=DaggerConfig.encoder,
        help="how the student reads its inputs: one flat vector (mlp), or the scans by convolution and the "
        "tracks as a set (set)",
    )
    dg.add_argument(
        "--device",
        choices=DEVICES,
        default=DaggerConfig.device,
        help="where the student is fitted (and, with --env-backend warp, the training episodes stepped): auto "
        "takes a CUDA GPU when PyTorch sees one",
    )
    dg.add_argument(
        "--env-backend",
        choices=ENV_BACKENDS,
        default=DaggerConfig.env_backend,
        help="where the training episodes are stepped: c (MuJoCo's C engine in the --workers) or warp (one MuJoCo "
        "Warp batch of --warp-envs on --device, the gpu extra; the student and teacher stay on the CPU); "
        "validation is always on the C engine",
    )
    dg.add_argument(
        "--no-velocity", dest="velocity", action="store_false", help="leave the measured (v, w) out of the inputs"
    )
    dg.add_argument(
        "--static-map",
        action="store_true",
        help="give the known map's ranges along the pooled beams among the inputs (as dagger_map.pt was "
        "trained; the shipped dagger's recipe leaves them out)",
    )
    add_renamed(dg, "--profile-sets", "--profiles", "profiles")
    dg.add_argument(
        "--profiles",
        default=",".join(SHIPPED_STUDENT_PROFILE_SETS),
        help="comma-separated profile sets (table1, release2022) or tiers (tier-dense, tier-fast, tier-mixed, "
        "tier-combined: their profiles, never their worlds) the training worlds are drawn from",
    )
    dg.add_argument("--out", type=Path, required=True, help="folder for data, checkpoints, policy.pt and the curve")


def _add_options(parser: argparse.ArgumentParser, config: type) -> None:
    """One `--name` per field the configuration offers, checked against its range."""
    from dynabarn.learn.configs import cli_options

    for name, kind, lo, hi, text, default in cli_options(config):
        parser.add_argument("--" + name.replace("_", "-"), type=ranged(kind, lo, hi), default=default, help=text)


@command
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

        if args.out.suffix == ".pt":  # the old spelling: a file
            print("note: --out FILE.pt is now --out DIR (DIR/policy.pt); taken as the file this once", file=sys.stderr)
            policy = args.out
        else:
            args.out.mkdir(parents=True, exist_ok=True)
            policy = args.out / "policy.pt"
        report = train_bc(
            args.data,
            policy,
            epochs=args.epochs,
            batch_size=args.batch_size,
            lr=args.lr,
            seed=args.seed,
            progress=lambda it: tqdm(it, desc="epochs", disable=None, leave=False),
        )
        print(
            f"wrote {policy}: {report.rows} rows, {report.epochs} epochs in {report.seconds:.1f} s, "
            f"loss {report.losses[0]:.4f} -> {report.losses[-1]:.4f}"
        )
        return 0
    if args.command == "dagger":
        return _train_dagger(args, tqdm)
    if args.command == "ppo":
        return _train_ppo(args, tqdm)
    from dynabarn.learn.configs import TD3Config, cli_options
    from dynabarn.learn.td3 import train_td3
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
        **{name: getattr(args, name) for name, *_ in cli_options(TD3Config)},
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
    from dynabarn.learn.configs import DaggerConfig, cli_options
    from dynabarn.learn.dagger import train_dagger

    profile_sets = [p for p in args.profiles.split(",") if p]
    cfg = DaggerConfig(  # checks the protocol and profile sets: one line before any worker starts
        protocol=args.protocol,
        teacher=args.teacher,
        head=args.head,
        encoder=args.encoder,
        device=args.device,
        env_backend=args.env_backend,
        velocity=args.velocity,
        static_map=args.static_map,
        profile_sets=profile_sets,
        **{name: getattr(args, name) for name, *_ in cli_options(DaggerConfig)},
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


def _train_ppo(args: argparse.Namespace, tqdm) -> int:
    from dynabarn.learn.configs import PPOConfig, cli_options
    from dynabarn.learn.ppo import train_ppo
    from dynabarn.learn.warp_worlds import require_warp
    from dynabarn.worldset import resolve_world

    require_warp()
    import warp as wp

    device = args.device
    if device == "auto":
        device = "cuda" if wp.is_cuda_available() else "cpu"
    try:
        wp.get_device(device)
    except (RuntimeError, ValueError):
        raise DynabarnError(
            f"--device {args.device}: Warp has no such device (it has: cpu{', cuda' * wp.is_cuda_available()})"
        ) from None
    if args.difficulty is not None and args.world_set is None:
        raise DynabarnError("--difficulty chooses within --world-set")
    if args.split is not None:
        worlds = {"split": args.split, "split_seed": args.split_seed, "procedural_worlds": args.procedural_worlds}
    elif args.world_set is not None:
        worlds = {"world_set": args.world_set, "difficulty": args.difficulty}
    else:
        worlds = str(resolve_world(args.world or "137", None))
    notes = dict(worlds) if isinstance(worlds, dict) else {"world": worlds}  # what the policy was trained on
    try:
        cfg = PPOConfig(
            **{name: getattr(args, name) for name, *_ in cli_options(PPOConfig)}, notes={**notes, "device": device}
        )
        report = train_ppo(
            worlds,
            args.out,
            cfg,
            device=device,
            progress=lambda total, initial=0: tqdm(total=total, initial=initial, desc="iterations"),
        )
    except ValueError as exc:  # the worlds' keywords, refused by the environment in one line
        raise DynabarnError(str(exc)) from None
    last = report["history"][-1]
    print(
        f"wrote {report['policy']} after {last['iteration']} iterations ({last['steps']:,} control steps) on "
        f"{device}; last rollout: {last['episodes']} episodes ended, {last['successes']} at the goal"
    )
    return 0
