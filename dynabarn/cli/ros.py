"""`dynabarn-ros`: a ROS 1 navigation stack drives the Jackal through a DynaBARN world, over
the BARN Challenge's topics; judged and recorded like `dynabarn-run`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from dynabarn.cli.common import (
    add_protocol,
    add_recording,
    add_trial_seed,
    add_world,
    make_parser,
    ranged,
    run_command,
)
from dynabarn.cli.episode import exit_status, print_result, run_recorded
from dynabarn.errors import DynabarnError


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-ros`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-ros",
        "Let a ROS 1 navigation stack drive the Jackal in a DynaBARN world: the bridge publishes /clock, "
        "/front/scan, /odometry/filtered, /tf and the goal as the BARN Challenge's Gazebo does, takes /cmd_vel, "
        "judges the episode with the protocol and records it to MCAP like dynabarn-run.",
    )
    add_world(parser)
    add_protocol(parser)
    add_trial_seed(parser)
    parser.add_argument(
        "--launch",
        default=None,
        metavar="COMMAND",
        help="command that starts the stack (run with ROS_MASTER_URI set, stopped after the episode), e.g. "
        "'roslaunch jackal_helper move_base_DWA.launch'; without it, start the stack yourself",
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
        help="wait for the stack's /cmd_vel every control period: deterministic, as fast as the stack (default)",
    )
    clock.add_argument(
        "--rate",
        type=ranged(float, 0.01, 100.0),
        default=None,
        help="instead run paced at RATE x real time, as Gazebo runs, with the latest /cmd_vel",
    )
    parser.add_argument(
        "--timeout", type=ranged(float, 0.1, 600.0), default=10.0, help="seconds a lockstep answer may take"
    )
    parser.add_argument(
        "--ready-timeout",
        type=ranged(float, 0.1, 600.0),
        default=30.0,
        help="seconds to wait for the stack to subscribe to the scan",
    )
    parser.add_argument(
        "--remap",
        action="append",
        default=[],
        metavar="FROM:=TO",
        help="rename a bridge topic, e.g. /front/scan:=/scan (repeatable)",
    )
    add_recording(parser, planner="ros", extra_keys=("bridge_ms_per_tick",))
    return parser


def ros_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(_ros_episode, args)


def _ros_episode(args: argparse.Namespace) -> int:
    from dynabarn.protocol import get_protocol
    from dynabarn.recording import default_run_path
    from dynabarn.ros.bridge import BridgeConfig, RosMaster, RosPlanner, bridge_overhead, ros_python
    from dynabarn.sim import Simulation
    from dynabarn.worldset import resolve_world

    for remap in args.remap:
        source, sep, target = remap.partition(":=")
        if not sep or not source.startswith("/") or not target.startswith("/"):
            raise DynabarnError(f"--remap {remap!r}: use /from:=/to, e.g. /front/scan:=/scan")
    sim = Simulation(resolve_world(args.world))
    protocol = get_protocol(args.protocol)
    ros_python()  # one clear line when ROS is missing, before a master is started
    config = BridgeConfig(
        lockstep=args.rate is None,
        rate=args.rate or 1.0,
        timeout=args.timeout,
        ready_timeout=args.ready_timeout,
        remaps=list(args.remap),
        launch=args.launch,
    )
    log_path = (
        None
        if args.no_log
        else args.log or default_run_path(args.runs_dir, sim.world.name, "ros", protocol.name, args.seed)
    )
    master = RosMaster.start(args.master)
    planner = RosPlanner(master, config)
    try:
        print(
            f"ROS master {master.uri}; {'lockstep' if config.lockstep else f'paced at {config.rate:g}x'}",
            file=sys.stderr,
        )
        result = run_recorded(sim, planner, protocol, seed=args.seed, log_path=log_path, planner_name="ros")
    finally:
        planner.finish("interrupted")  # run_episode has done so already unless something broke
        master.close()
    overhead = bridge_overhead(planner)
    print_result(result, as_json=args.json, recording=log_path, extra={"bridge_ms_per_tick": round(overhead, 3)})
    if not args.json:
        print(f"bridge overhead {overhead:.2f} ms per control period", file=sys.stderr)
    return exit_status(result, as_json=args.json)
