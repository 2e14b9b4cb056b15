"""`dynabarn-export`: recordings as ROS bags (ROS 1 or ROS 2 with MCAP storage)."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import add_renamed, command, make_parser, run_command
from dynabarn.errors import DynabarnError


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-export`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-export",
        "Write a recording as a ROS bag with ROS message types (sensor_msgs/LaserScan, nav_msgs/Odometry, "
        "tf2_msgs/TFMessage, geometry_msgs/Twist, visualization_msgs/MarkerArray, std_msgs/String), for rosbag, "
        "rostopic, rviz and ROS 2 tools. Needs the ros extra (rosbags).",
    )
    parser.add_argument("recording", type=Path, help="MCAP recording (from dynabarn-run, -bench or -ros)")
    parser.add_argument(
        "--format",
        choices=["rosbag1", "rosbag2"],
        default="rosbag1",
        help="rosbag1 = a ROS 1 .bag (Noetic types); rosbag2 = a ROS 2 bag folder, MCAP storage, CDR (Humble types)",
    )
    parser.add_argument(
        "--bag", type=Path, default=None, help="bag to write (default: the recording's name with .bag, or _rosbag2)"
    )
    add_renamed(parser, "--out", "--bag", "bag", type=Path)
    return parser


@command
def export_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(_export, args)


def _export(args: argparse.Namespace) -> int:
    from dynabarn.recording import read_recording
    from dynabarn.ros.export import export_bag

    rec = read_recording(args.recording)
    if rec.truncated:
        print(f"warning: {args.recording} is truncated ({rec.error}); exporting up to the cut", file=sys.stderr)
    suffix = ".bag" if args.format == "rosbag1" else "_rosbag2"
    out = args.bag or args.recording.with_name(args.recording.stem + suffix)
    if not out.parent.is_dir():
        raise DynabarnError(f"--out {out}: the folder {out.parent} does not exist")
    t0 = time.perf_counter()
    counts = export_bag(rec, out, args.format)
    print(
        f"wrote {out} ({args.format}): {sum(counts.values())} messages on {len(counts)} topics "
        f"in {time.perf_counter() - t0:.2f} s"
    )
    return 0
