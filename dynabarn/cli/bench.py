"""`dynabarn-bench`: sweeps of planners x worlds x trials, their summary, and the golden set."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.bench_check import (
    check_command,
    command_line_config,
    compare_command,
    golden_command,
    report_so_far,
)
from dynabarn.cli.common import (
    SET_HELP,
    add_jobs,
    add_protocol,
    add_sim_settings,
    command,
    make_parser,
    ranged,
    run_command,
    sim_settings,
)
from dynabarn.errors import DynabarnError
from dynabarn.ros.stacks import STACKS


# Over 80 lines on purpose: one parser, every option with its help, in the order --help shows.
def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-bench`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-bench",
        "Run planners over a world set and trials in parallel; resumable; summary table, CSV, Markdown "
        "and a Fig. 5-style PNG in --out.",
    )
    # Imported once the parser exists: make_parser chose MuJoCo's OpenGL platform, which
    # MuJoCo reads when first imported (these modules import it).
    from dynabarn.bench.verify import DEFAULT_SAMPLE
    from dynabarn.planners import planner_presets

    parser.add_argument(
        "--planner",
        default="dwa",
        help="planner(s), comma separated, e.g. dwa,teb; NAME@PRESET runs a named preset as its own row "
        "(dwa@dwa_dynabarn_authors, teb@teb_ros_defaults); MODULE:CLASS or FILE.py:CLASS runs a planner from its "
        "code, unpackaged (rows record the module, or the file's name and sha256); with --verify, the planners from "
        "code that the rows name (--verify never loads code a row names)",
    )
    parser.add_argument(
        "--no-floor",
        action="store_true",
        help="do not add the blind floor: without it, `straight` (drive at the goal at 2 m/s, avoid nothing) "
        "runs on the same worlds and seeds, and the summary gives every planner's skill over it",
    )
    parser.add_argument(
        "--planner-config",
        default=None,
        help="parameters for every planner: key=value[,...], a .json file, or a named preset "
        + f"({', '.join(planner_presets())}; each file in dynabarn/planners/presets/ says its source); with "
        "--verify, KEY=VALUE for the other options a row may not supply (e.g. nav_workspace, stack_log, master)",
    )
    parser.add_argument(
        "--policy",
        type=Path,
        default=None,
        help="weights for bc, td3 or dagger (default: the policy shipped in the package); with --verify, the "
        "policy file to use for rows that name one (a row never supplies it)",
    )
    parser.add_argument(
        "--ros-launch",
        default=None,
        metavar="COMMAND",
        help="with --planner ros: the command that starts the ROS stack for each episode (each worker runs "
        "its own roscore); with --verify, the command for rows of a ROS stack (a row never supplies it)",
    )
    parser.add_argument(
        "--ros-stack",
        default=None,
        choices=sorted(STACKS),
        help="with --planner ros: a stack of ours instead of --ros-launch (move_base from `make ros-nav`; "
        "move_base_teb also needs `make ros-teb`; nav2_dwb and nav2_mppi, on ROS 2, from `make nav2`)",
    )
    parser.add_argument(
        "--set", default="paper60", help=SET_HELP + "; with --verify, a further folder the rows' world files may be in"
    )
    parser.add_argument("--worlds", default=None, help="only these world ids, e.g. 0,5,100-119")
    parser.add_argument("--trials", type=ranged(int, 1, 10_000), default=10, help="trials (seeds 0..N-1) per world")
    add_protocol(parser)
    add_sim_settings(parser)
    add_jobs(parser)
    parser.add_argument("--backend", choices=["local", "ray"], default="local", help="where episodes run")
    parser.add_argument(
        "--address",
        default=None,
        help="Ray cluster address (ray backend); default: $RAY_ADDRESS, else a local Ray on 127.0.0.1",
    )
    parser.add_argument(
        "--record", choices=["none", "failures", "all"], default="none", help="which episodes to keep as MCAP"
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="output folder (results.jsonl, summary, fig5.png); required for a sweep"
    )
    parser.add_argument("--force", action="store_true", help="start over in an --out that holds another sweep")
    golden = parser.add_argument_group(
        "golden set",
        "about 30 committed episodes that must come out the same on every machine (docs/reproducibility.md)",
    )
    golden.add_argument(
        "--verify-golden",
        action="store_true",
        help="re-run the golden set and print every field that differs from the committed results; exit 1 if any",
    )
    golden.add_argument(
        "--update-golden", action="store_true", help="re-run the golden set and rewrite the committed results"
    )
    golden.add_argument(
        "--reference",
        type=Path,
        default=None,
        help="folder with the reference data the imported golden worlds need (dynabarn60.json, barn300_static.json); "
        "default: ../shared/reference beside the repository; cases that need it are skipped without it",
    )
    checking = parser.add_argument_group(
        "looking into results", "a sweep's report and re-running anyone's results (docs/concepts/report.md)"
    )
    checking.add_argument(
        "--report",
        type=Path,
        default=None,
        metavar="DIR",
        help="write DIR/report.html for an existing results folder (every sweep writes its own at the end)",
    )
    checking.add_argument(
        "--verify",
        type=Path,
        default=None,
        metavar="RESULTS",
        help="re-run rows of a results file or folder on this machine and compare each with its row (every field "
        "but the machine's). Exit 0: every sampled row reproduces; 1: a row differs; 3: nothing differs, but some "
        "rows could not be checked here (each is printed as 'not checked' with what would let it run: an extra, a "
        "ROS stack, a planner this install lacks, or an option only you may give). The rows are data: only planners "
        "installed here run, and a row whose planner option names a program, a file or an address (a policy, a ROS "
        "launch line) runs only with the value you give (--policy, --ros-launch, --planner-config KEY=VALUE); "
        "world files are taken only from the results folder, this package's world sets and --set",
    )
    checking.add_argument(
        "--compare",
        nargs=2,
        type=Path,
        default=None,
        metavar=("A", "B"),
        help="two planners side by side on the episodes both ran: A and B are results folders (the same one twice "
        "for two planners of one sweep); --planner A_PLANNER,B_PLANNER names them where a folder holds more than "
        "one besides the floor. Prints per difficulty the paired difference of success with its 95%% interval and "
        "the worlds where they disagree; with --out DIR, also DIR/report.html (the two side by side) and "
        "DIR/comparison.json",
    )
    checking.add_argument(
        "--sample",
        type=_sample,
        default=DEFAULT_SAMPLE,
        help=f"with --verify: how many rows, drawn by a fixed seed (default {DEFAULT_SAMPLE}), or 'all'",
    )
    return parser


def _sample(text: str) -> int | None:
    """`--sample`: a whole number of rows, or `all` (None)."""
    return None if text == "all" else ranged(int, 1, 10**9)(text)


COMPARE_OPTIONS = {"compare", "planner", "out", "debug"}
"""The options that apply to `--compare`."""
GOLDEN_OPTIONS = {"verify_golden", "update_golden", "reference", "jobs", "debug"}
"""The options that apply to `--verify-golden` and `--update-golden`."""
CHECK_OPTIONS = {
    "report",
    "verify",
    "sample",
    "jobs",
    "debug",
    "policy",
    "ros_launch",
    "planner_config",
    "set",
    "planner",
}
"""The options that apply to `--report` and `--verify` (with `--verify`: `--policy`,
`--ros-launch` and `--planner-config` name what a row may not, `--set` where its worlds are)."""
VERIFY_ONLY = {"sample", "policy", "ros_launch", "planner_config", "set", "planner"}
"""Of those, the ones that mean something only with `--verify`."""


def _given(argv: Sequence[str] | None) -> list[str]:
    """The options written on the command line (not those left at their defaults)."""
    probe = build_parser()
    for action in probe._actions:
        action.default = argparse.SUPPRESS
    return list(vars(probe.parse_args(argv)))


@command
def bench_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    given = _given(argv)  # the options written on the command line, read once
    if args.verify_golden or args.update_golden:
        # The golden set is fixed (its cases name their planners, worlds and seeds): a sweep's
        # choices would be silently ignored, so they are refused.
        ignored = ["--" + key.replace("_", "-") for key in given if key not in GOLDEN_OPTIONS]
        if ignored:
            parser.error(f"{', '.join(ignored)}: not for the golden set, which runs its own committed cases")
        return run_command(golden_command, args)
    if args.compare is not None:
        ignored = ["--" + key.replace("_", "-") for key in given if key not in COMPARE_OPTIONS]
        if ignored:
            parser.error(f"{', '.join(ignored)}: not for --compare, which reads two existing results folders")
        args.planner_given = "planner" in given
        return run_command(compare_command, args)
    if args.report is not None or args.verify is not None:
        ignored = ["--" + key.replace("_", "-") for key in given if key not in CHECK_OPTIONS]
        if ignored:
            parser.error(f"{', '.join(ignored)}: not for --report or --verify, which read an existing results folder")
        if args.verify is None:
            unused = ["--" + key.replace("_", "-") for key in given if key in VERIFY_ONLY]
            if unused:
                parser.error(f"{', '.join(unused)}: only with --verify (--report re-runs nothing)")
        args.set_given = "set" in given  # --set's default names no folder of the rows'
        args.planner_given = "planner" in given
        return run_command(check_command, args)
    if "sample" in given:
        parser.error("--sample: only with --verify")
    if args.out is None:
        parser.error("--out is required for a sweep")
    args.argv = list(sys.argv[1:] if argv is None else argv)  # metadata.json keeps every invocation's
    return run_command(_bench, args)


def _bench(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from dynabarn import bench, worldset
    from dynabarn.bench.results import RECORDINGS
    from dynabarn.bench.summary import FLOOR
    from dynabarn.planners import get_planner, planner_spec
    from dynabarn.protocol import get_protocol

    if args.trials < 1 or args.jobs < 1:
        raise DynabarnError("--trials and --jobs must be at least 1")
    config = command_line_config(args)
    names = [p.strip() for p in args.planner.split(",")]
    if not any(names):
        raise DynabarnError(f"--planner {args.planner!r}: name at least one planner, e.g. dwa or dwa,teb")
    if not all(names):  # `straight,,stop`: a name left out by mistake, not an empty planner
        raise DynabarnError(f"--planner {args.planner!r}: an empty name between commas; name planners as dwa,teb")
    specs = [planner_spec(p) for p in dict.fromkeys(names)]
    planners = [(name, preset | config, label) for name, preset, label in specs]
    for name, cfg, _ in planners:
        get_planner(name, **cfg)  # fail fast on an unknown planner or bad configuration
    if not args.no_floor and FLOOR not in {label for *_, label in planners}:
        planners.insert(0, (FLOOR, {}, FLOOR))  # first: a sweep cut short still has its floor
    protocol = get_protocol(args.protocol)
    worlds = worldset.world_set(args.set, worldset.parse_ids(args.worlds))
    jobs = bench.make_jobs(
        planners,
        worlds,
        protocol,
        args.trials,
        record=args.record,
        recordings_dir=args.out / RECORDINGS,
        sim=sim_settings(args),
    )
    if args.out.exists() and not args.out.is_dir():
        raise DynabarnError(f"--out {args.out}: exists and is not a folder")

    def progress(stream, total):
        return tqdm(stream, total=total, desc="episodes", unit="ep", disable=None, smoothing=0.05)

    # One writer per folder: run_sweep holds the lock over the metadata check (and --force's
    # clean-up), the rows, the summary and the report.
    try:
        report = bench.run_sweep(
            jobs,
            args.out,
            backend=args.backend,
            n_workers=args.jobs,
            address=args.address,
            progress=progress,
            arguments=bench.jsonable_args(args),
            argv=args.argv,
            force=args.force,
            title=f"{args.set}, protocol {protocol.name}, {args.trials} trials",
        )
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM; the workers went with the pool
        report_so_far(args.out)
        raise type(exc)(f"finished episodes are in {args.out / bench.RESULTS}; rerun to resume") from None
    print(bench.format_table(report.summary))
    paths = report.paths
    print(
        f"{report.ran} episodes run, {report.skipped} already done, {report.errors} errors, "
        f"{report.wall_time:.1f} s; wrote {paths['csv']}, {paths['md']}, {paths['png']}, {paths['html']}"
    )
    return _report_errors(report.rows, args.out)


def _report_errors(rows: list[dict], out: Path) -> int:
    """Episodes that ended in `error` did not measure the planner: say so loudly (stderr) and
    exit 1, so a script or CI cannot take the table for a result."""
    from dynabarn.recording.topics import stopped_by_a_topic

    cut = [r for r in rows if r.get("recording_error")]
    if cut:
        why = str(cut[0]["recording_error"])
        advice = (
            "fix or uninstall the package of that recording topic, then run again"
            if stopped_by_a_topic(why)
            else "free space and run the same command again to record them whole"
        )
        print(f"WARNING: {len(cut)} recordings were cut short ({why}); their results stand; {advice}", file=sys.stderr)
    errors = [r for r in rows if r.get("outcome") == "error"]
    if not errors:
        return 1 if cut else 0
    print(f"ERROR: {len(errors)} of {len(rows)} episodes ended in an error, not an outcome:", file=sys.stderr)
    for r in errors[:5]:
        print(f"  {r.get('planner')} {r.get('world')} seed {r.get('seed')}: {r.get('reason')}", file=sys.stderr)
    if len(errors) > 5:
        print(f'  ... and {len(errors) - 5} more (outcome "error" in {out / "results.jsonl"})', file=sys.stderr)
    print(
        "their rows count as failures in the table above; infrastructure failures (disk full, a killed worker) "
        "run again when you rerun the command; for planner errors fix the cause and rerun with --force",
        file=sys.stderr,
    )
    return 1
