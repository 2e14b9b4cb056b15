"""`dynabarn-demos`: collect synthetic demonstrations and export datasets for learning."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    SET_HELP,
    add_jobs,
    add_protocol,
    add_renamed,
    command,
    make_parser,
    ranged,
    run_command,
    subcommands,
)
from dynabarn.errors import DynabarnError


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-demos`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser("dynabarn-demos", "Collect synthetic demonstrations and export datasets for learning.")
    # Imported once the parser exists: make_parser chose MuJoCo's OpenGL platform, which
    # MuJoCo reads when first imported (these modules import it).
    from dynabarn.demos.dataset import DEFAULT_LOOKAHEAD

    sub = subcommands(parser)
    ex = sub.add_parser(
        "export",
        help="recordings -> dataset.npz of (720 ranges, local goal) -> (v, w) rows",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ex.add_argument("demos", nargs="+", type=Path, help="recordings or folders of recordings")
    ex.add_argument("--dataset", type=Path, required=True, help="dataset file to write (.npz)")
    add_renamed(ex, "--out", "--dataset", "dataset", type=Path)
    ex.add_argument("--all", action="store_true", help="keep unsuccessful episodes too")
    ex.add_argument(
        "--lookahead",
        type=ranged(float, 0.1, 30.0),
        default=DEFAULT_LOOKAHEAD,
        help="local goal distance along the plan [m]",
    )
    co = sub.add_parser(
        "collect",
        help="record oracle demonstrations at scale (synthetic, marked so)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    co.add_argument("--set", default="paper60", help=SET_HELP)
    co.add_argument("--worlds", default=None, help="only these world ids, e.g. 0,5,100-119")
    co.add_argument("--trials", type=ranged(int, 1, 10_000), default=1, help="seeds 0..N-1 per world")
    add_protocol(co)
    co.add_argument("--planner", default="oracle", help="demonstrator planner")
    add_jobs(co)
    co.add_argument("--out", type=Path, default=Path("demos"), help="folder of demonstrations")
    return parser


@command
def demos_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(_demos_export if args.command == "export" else _demos_collect, args)


def _demos_export(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from dynabarn.demos.dataset import export

    if args.dataset.suffix != ".npz":
        raise DynabarnError(f"--dataset must be a .npz file, got {args.dataset.name!r}")
    meta = export(
        args.demos,
        args.dataset,
        include_all=args.all,
        lookahead=args.lookahead,
        progress=lambda it: tqdm(it, desc="reading", unit="rec", disable=None, leave=False),
    )
    print(f"wrote {args.dataset}: {meta['episodes']} episodes, {meta['rows']} rows ({len(meta['skipped'])} skipped)")
    return 0


def _demos_collect(args: argparse.Namespace) -> int:

    from dynabarn import bench, worldset
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol

    get_planner(args.planner)
    protocol = get_protocol(args.protocol)
    worlds = worldset.world_set(args.set, worldset.parse_ids(args.worlds))
    # One writer per folder: a sweep (or another collection) into the same folder at once is
    # refused by the lock a sweep takes.
    with bench.locked(args.out):
        return _collect_into(args, worlds, protocol)


def _collect_into(args: argparse.Namespace, worlds, protocol) -> int:
    from tqdm import tqdm

    from dynabarn import bench
    from dynabarn.demos.teleop import MANIFEST, append_manifest, listed_files

    listed = listed_files(args.out)  # a damaged manifest is one line before anything runs
    jobs = bench.make_jobs([(args.planner, {})], worlds, protocol, args.trials, record="all", recordings_dir=args.out)
    report = bench.run_sweep(
        jobs,
        args.out / ".collect",
        n_workers=args.jobs,
        folder=False,  # the rows only: the demonstrations' manifest is the folder's record
        progress=lambda stream, total: tqdm(stream, total=total, desc="demos", unit="ep", disable=None),
    )
    missing = 0
    for row in sorted(report.rows, key=lambda r: r["key"]):
        name = Path(row.get("recording", "")).name
        if not name or not (args.out / name).is_file():  # not recorded (a full disk): not listed
            missing += 1
            continue
        if name in listed:
            continue
        append_manifest(
            args.out,
            {
                "file": name,
                "world": row.get("world"),
                "world_id": row["world_id"],
                "protocol": row["protocol"],
                "seed": row["seed"],
                "outcome": row["outcome"],
                "reason": row.get("reason", ""),
                "time": row.get("time"),
                "operator": "",
                "source": "oracle" if args.planner == "oracle" else "planner",
            },
        )
    ok = sum(r["outcome"] == "success" for r in report.rows)
    print(f"{len(report.rows)} demonstrations in {args.out} ({ok} successful); manifest: {args.out / MANIFEST}")
    if missing:
        raise DynabarnError(
            f"{missing} of {len(report.rows)} episodes left no recording in {args.out} (a full disk?); "
            "run the same command again once there is room"
        )
    return 0
