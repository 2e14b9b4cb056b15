"""`dynabarn-ros`: a ROS 1 or ROS 2 navigation stack drives the Jackal through a DynaBARN
world, over the BARN Challenge's topics; judged and recorded like `dynabarn-run`."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    add_protocol,
    add_recording,
    add_trial_seed,
    add_world,
    command,
    make_parser,
    ranged,
    run_command,
)
from dynabarn.cli.episode import exit_status, print_result
from dynabarn.errors import DynabarnError
from dynabarn.ros import READY_WHEN
from dynabarn.ros.nav_build import WORKSPACE_ENV
from dynabarn.ros.stacks import STACKS


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-ros`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-ros",
        "Let a ROS 1 or ROS 2 navigation stack drive the Jackal in a DynaBARN world: the bridge publishes /clock, "
        "/front/scan, /odometry/filtered, /tf and the goal as the BARN Challenge's Gazebo does, takes /cmd_vel, "
        "judges the episode with the protocol and records it to MCAP like dynabarn-run.",
    )
    add_world(parser)
    add_protocol(parser)
    add_trial_seed(parser)
    _add_stack(parser)
    parser.add_argument(
        "--ros",
        type=int,
        choices=(1, 2),
        default=None,
        help="the ROS the stack runs on: 1, Debian's ROS 1 with a master of our own; 2, the ROS 2 Jazzy "
        "`make ros2-core` built, in a DDS domain of our own kept on this machine (default: the --stack's ROS, "
        "else 1)",
    )
    parser.add_argument(
        "--bag",
        action="store_true",
        help="also write the recording as a bag of the stack's ROS beside it (ROS 1: NAME.bag; ROS 2: the folder "
        "NAME_rosbag2, MCAP storage), for rosbag / ros2 bag (needs rosbags: pip install 'dynabarn[ros]'); "
        "off by default",
    )
    parser.add_argument(
        "--ros2-bag",
        type=Path,
        default=None,
        metavar="DIR",
        help="ROS 2: also record the run live with rosbag2 (`ros2 bag record --all-topics`, MCAP storage) into the "
        "new folder DIR: every topic the bridge and the stack publish (its plans and costmaps too) on the "
        "bridge's clock, from the boot on; the episode starts once the recorder has subscribed to each of the "
        "bridge's topics (needs rosbag2 in the core: make ros2-core); off by default",
    )
    parser.add_argument(
        "--ros2-workspace",
        type=Path,
        default=None,
        help="where `make ros2-core` built ROS 2 (default: $DYNABARN_ROS2_WS or ~/.cache/dynabarn/ros2)",
    )
    parser.add_argument(
        "--master",
        default=None,
        metavar="URI",
        help="use this ROS master (default: start a master of our own on a free port, listening on 127.0.0.1 only)",
    )
    clock = parser.add_mutually_exclusive_group()
    clock.add_argument(
        "--lockstep",
        action="store_true",
        default=True,
        help="run each control period at once, then wait for the stack's /cmd_vel (see --grace): as fast as the stack, "
        "and the same episode every time for a stack that answers each scan (default)",
    )
    clock.add_argument(
        "--rate",
        type=ranged(float, 0.01, 100.0),
        default=None,
        help="instead run paced at RATE x real time, as Gazebo runs, with the latest /cmd_vel",
    )
    _add_timing(parser)
    parser.add_argument(
        "--remap",
        action="append",
        default=[],
        metavar="FROM:=TO",
        help="rename a bridge topic, e.g. /front/scan:=/scan (repeatable)",
    )
    add_recording(
        parser,
        planner="ros",
        extra_keys=("bridge_ms_per_tick", "held_periods", "periods_after_navigation_ended", "stack_log"),
    )
    return parser


def _add_stack(parser: argparse.ArgumentParser) -> None:
    """Which stack runs and where its output goes."""
    stack = parser.add_mutually_exclusive_group()
    stack.add_argument(
        "--launch",
        default=None,
        metavar="COMMAND",
        help="command that starts the stack (run with ROS_MASTER_URI set, stopped after the episode), e.g. "
        "'roslaunch jackal_helper move_base_DWA.launch'; without it (or --stack), start the stack yourself",
    )
    stack.add_argument(
        "--stack",
        default=None,
        choices=sorted(STACKS),
        help="a stack of ours: "
        + "; ".join(f"{name}: {s.about}" for name, s in STACKS.items())
        + " (move_base: `make ros-nav`; Nav2: `make nav2`, and runs on ROS 2)",
    )
    parser.add_argument(
        "--nav-workspace",
        type=Path,
        default=None,
        metavar="DIR",
        help=f"the catkin workspace `make ros-nav` built move_base in (default: ${WORKSPACE_ENV} or "
        "~/.cache/dynabarn/ros_nav), or for a Nav2 stack the prefix `make nav2` built (default: $DYNABARN_NAV2_WS "
        "or ~/.cache/dynabarn/nav2)",
    )
    parser.add_argument(
        "--stack-log",
        type=Path,
        default=None,
        metavar="FILE",
        help="where the stack's output goes (default: beside the recording as NAME.stack.log, or "
        "~/.ros/log/dynabarn-ros-TIME.log with --no-log); never this command's stdout",
    )


def _add_timing(parser: argparse.ArgumentParser) -> None:
    """The boot, the clock and the lockstep's waits."""
    parser.add_argument(
        "--timeout",
        type=ranged(float, 0.1, 600.0),
        default=None,
        help="wall seconds without any /cmd_vel (lockstep) before the episode ends as an error (default: 10, or "
        "the --stack's own: 60 for Nav2, whose recoveries wait in silence)",
    )
    parser.add_argument(
        "--grace",
        type=ranged(float, 0.001, 600.0),
        default=0.5,
        help="wall seconds a lockstep control period waits for a /cmd_vel after its scan; then the last command "
        "holds for that period, as a stack that is planning or runs a slower loop would leave it (default: 0.5)",
    )
    parser.add_argument(
        "--ready",
        choices=READY_WHEN,
        default="command",
        help="when the stack counts as started: 'command' (it sent a /cmd_vel after the goal) or 'subscribed' "
        "(it subscribed to the scan); until then the robot stands at its spawn on a running clock (default: command)",
    )
    parser.add_argument(
        "--ready-timeout",
        type=ranged(float, 0.1, 600.0),
        default=None,
        help="wall seconds the stack may take to start before the episode ends as an error naming what never "
        "happened (default: 30, or the --stack's own: 90 for Nav2, which brings up its servers one by one)",
    )
    parser.add_argument(
        "--stack-rate",
        type=ranged(float, 0.0, 1000.0),
        default=0.0,
        metavar="HZ",
        help="the rate of the stack's control loop when it runs from a timer on ROS time (move_base: its "
        "controller_frequency): in lockstep the clock stands still at each tick where that timer fires until the "
        "loop's /cmd_vel comes, so the loop runs at its rate; 0: the stack answers each scan (default: 0; "
        "--stack knows its own)",
    )
    parser.add_argument(
        "--clock-step",
        type=ranged(float, 0.0001, 0.1),
        default=0.005,
        help="simulated seconds between /clock messages, so a stack's timers fire at their rates (default: 0.005, "
        "the physics step)",
    )


@command
def ros_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(_ros_episode, args)


def _bridge_config(args: argparse.Namespace, workspace: Path | None, stack_log: Path | None) -> dict:
    """The `ros` planner's configuration from the command's options (`ros.bridge.BridgeConfig`,
    and the master to use)."""
    return {
        "lockstep": args.rate is None,
        "rate": args.rate or 1.0,
        "timeout": args.timeout,
        "grace": args.grace,
        "ready": args.ready,
        "ready_timeout": args.ready_timeout,
        "clock_step": args.clock_step,
        "stack_rate": args.stack_rate,
        "remaps": list(args.remap),
        "launch": args.launch,
        "stack": args.stack,
        "nav_workspace": str(workspace) if workspace else None,
        "stack_log": str(stack_log) if stack_log else None,
        "master": args.master,
        "announce": True,
        **({"ros": 2} if args.ros == 2 else {}),
        **({"ros2_workspace": str(args.ros2_workspace.expanduser().resolve())} if args.ros2_workspace else {}),
        **({"ros2_bag": str(args.ros2_bag)} if args.ros2_bag is not None else {}),
    }


def _check_ros(args: argparse.Namespace) -> None:
    """--ros (the --stack's where not given) and what it needs, built: one line otherwise."""
    from dynabarn.ros.bridge_config import ros_python

    stack_ros = STACKS[args.stack].ros if args.stack else None
    if args.ros is None:
        args.ros = stack_ros or 1
    if stack_ros is not None and stack_ros != args.ros:
        raise DynabarnError(f"--stack {args.stack} runs on ROS {stack_ros}: leave out --ros {args.ros}")
    if args.ros == 2:
        if args.master:
            raise DynabarnError("--ros 2: --master is ROS 1's (each ROS 2 bridge takes a DDS domain of its own)")
        from dynabarn.ros.domain import built_setup

        built_setup(args.ros2_workspace)  # one clear line when ROS 2 is not built
        if args.ros2_bag is not None:
            _check_ros2_bag(args)
    elif args.ros2_bag is not None:
        raise DynabarnError("--ros2-bag records with ROS 2's rosbag2: it needs --ros 2 (ROS 1: --bag)")
    else:
        ros_python()  # one clear line when ROS is missing, before a master is started


def _check_ros2_bag(args: argparse.Namespace) -> None:
    """--ros2-bag: a new folder, and rosbag2 in the core; one line otherwise."""
    from dynabarn.ros import ros2_build
    from dynabarn.ros.bridge import check_bag_folder

    args.ros2_bag = args.ros2_bag.expanduser().resolve()
    core = args.ros2_workspace.expanduser().resolve() if args.ros2_workspace else ros2_build.default_workspace()
    record = ros2_build.built(core) or {}
    if "ros2bag" not in record.get("packages", ()):
        raise DynabarnError("--ros2-bag: rosbag2 is not in the ROS 2 core; build it: make ros2-core ROS2_SRC=DIR")
    args.ros2_bag.parent.mkdir(parents=True, exist_ok=True)
    try:
        check_bag_folder(args.ros2_bag)  # the bridge's own check, before anything starts
    except DynabarnError as exc:
        raise DynabarnError(f"--ros2-bag {exc}") from None


def _ros_episode(args: argparse.Namespace) -> int:
    from dynabarn.mjcf import read_world
    from dynabarn.protocol import get_protocol
    from dynabarn.recording import default_run_path
    from dynabarn.ros.bridge_config import remap_problem
    from dynabarn.ros.stacks import stack_command
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.worldset import resolve_world

    for remap in args.remap:
        problem = remap_problem(remap)
        if problem:
            raise DynabarnError(f"--remap {remap!r}: {problem}")
    if args.launch is not None and not args.launch.strip():
        raise DynabarnError("--launch '': an empty command; leave --launch out to start the stack yourself")
    if args.bag and args.no_log:
        raise DynabarnError("--bag writes the recording as a bag: it needs the recording (leave out --no-log)")
    if args.stack_log is not None and args.stack_log.is_dir():
        raise DynabarnError(f"--stack-log {args.stack_log}: a folder; name a file for the stack's output")
    world_path = resolve_world(args.world, args.set)
    world_name = read_world(world_path).name  # parsed and checked; compiled by run_spec
    protocol = get_protocol(args.protocol)
    _check_ros(args)
    workspace = args.nav_workspace.expanduser().resolve() if args.nav_workspace else None
    if args.stack:
        stack_command(args.stack, workspace)  # one clear line when move_base is not built
    launch = args.launch or args.stack
    log_path = (
        None
        if args.no_log
        else args.log or default_run_path(args.runs_dir, world_name, "ros", protocol.name, args.seed)
    )
    stack_log = None
    if launch:
        stack_log = args.stack_log or (
            Path(log_path).with_suffix(".stack.log")
            if log_path
            else Path.home() / ".ros" / "log" / f"dynabarn-ros-{time.strftime('%Y%m%d-%H%M%S')}.log"
        )
        stack_log.parent.mkdir(parents=True, exist_ok=True)
    config = _bridge_config(args, workspace, stack_log)

    # The `ros` planner of the registry (`ros.bridge.ros_planner`): a bad setting (an
    # unbalanced quote in --launch) is one line before a master starts. The runner ends the
    # stack, the node and the master (the planner's `finish`) whatever happens.
    spec = EpisodeSpec.make(world_path, "ros", protocol, config=config, seed=args.seed)
    run = run_spec(spec, record_to=log_path)
    result, report = run.result, run.planner_report
    overhead, held = report["bridge_ms_per_tick"], report["held_periods"]
    extra = {**report, "stack_log": str(stack_log) if stack_log else None}
    if args.ros2_bag is not None:
        extra["ros2_bag"] = str(args.ros2_bag)
    if args.bag and run.recording is not None:  # the stack's own ROS reads it: rosbag, ros2 bag
        from dynabarn.recording import read_recording
        from dynabarn.ros.export import export_bag

        bag = run.recording.with_name(run.recording.stem + (".bag" if args.ros == 1 else "_rosbag2"))
        export_bag(read_recording(run.recording), bag, "rosbag1" if args.ros == 1 else "rosbag2")
        extra["bag"] = str(bag)
    print_result(result, as_json=args.json, recording=log_path, extra=extra)
    if not args.json:
        held_note = f"; {held} control periods without a /cmd_vel (the last command held)" if held else ""
        ended = report.get("periods_after_navigation_ended") or 0
        held_note += f"; the stack's navigation ended, the robot stood for {ended} periods" if ended else ""
        cost = "n/a (no control period ran)" if overhead is None else f"{overhead:.2f} ms per control period"
        print(f"bridge overhead {cost}{held_note}", file=sys.stderr)
    return exit_status(result, as_json=args.json)
