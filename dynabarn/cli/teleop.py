"""`dynabarn-teleop`: drive the Jackal yourself in MuJoCo's viewer and record a demonstration."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    EXIT_EPISODE_ERROR,
    add_protocol,
    add_renamed,
    add_trial_seed,
    add_world,
    command,
    make_parser,
    plain_name,
    ranged,
    run_command,
)
from dynabarn.cli.live import exit_code
from dynabarn.errors import DynabarnError
from dynabarn.provenance import has_display


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-teleop`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-teleop",
        "Drive the Jackal yourself in MuJoCo's viewer and record a demonstration. Keys: Up/Down speed, "
        "Left/Right turn, Space stop, 1 slow mode, 2 fast mode, Escape end. A gamepad works when pygame sees one.",
    )
    add_world(parser)
    add_protocol(parser)
    add_trial_seed(parser)
    parser.add_argument(
        "--operator",
        type=plain_name,
        default="human",
        help="your name, stored with the demonstration and part of its file name (letters, digits, ._+-)",
    )
    parser.add_argument("--demos-dir", type=Path, default=Path("demos"), help="folder of demonstrations")
    parser.add_argument(
        "--log",
        type=Path,
        default=None,
        help="MCAP file to record to (default: DEMOS_DIR/<world>_<operator>_<NNN>.mcap)",
    )
    add_renamed(parser, "--out", "--log", "log", type=Path)
    parser.add_argument(
        "--speed", type=ranged(float, 0.1, 10.0), default=1.0, help="simulated seconds per wall-clock second"
    )
    return parser


@command
def teleop_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return exit_code(run_command(_teleop, args))


def _teleop(args: argparse.Namespace) -> int:

    from dynabarn.demos.teleop import append_manifest, next_demo_path, run_teleop
    from dynabarn.metrics import Outcome
    from dynabarn.mjcf import read_world
    from dynabarn.protocol import get_protocol
    from dynabarn.worldset import resolve_world

    if not has_display():
        raise DynabarnError("dynabarn-teleop needs a display (or Xvfb); none is set")
    if args.speed <= 0:
        raise DynabarnError("--speed must be positive")
    world_path = resolve_world(args.world, args.set)
    protocol = get_protocol(args.protocol)
    world = read_world(world_path)
    out = args.log or next_demo_path(args.demos_dir, world.name, args.operator)
    result, pad = run_teleop(world_path, protocol, out, operator=args.operator, seed=args.seed, speed=args.speed)
    append_manifest(
        out.parent,
        {
            "file": out.name,
            "world": world.name,
            "world_id": world.world_id,
            "protocol": protocol.name,
            "seed": args.seed,
            "outcome": result.outcome.value,
            "reason": result.reason,
            "time": result.time,
            "operator": args.operator,
            "source": "human",
            "gamepad": pad,
        },
    )
    print(result.summary())
    print(f"demonstration: {out} (manifest: {out.parent / 'manifest.jsonl'})")
    operator_stop = result.outcome is Outcome.ERROR and result.reason == "ended by the operator"
    return EXIT_EPISODE_ERROR if result.outcome is Outcome.ERROR and not operator_stop else 0
