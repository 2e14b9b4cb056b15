"""Command-line entry points, one module per command (common: what they share).

Each `*_main(argv)` returns an exit code; `[project.scripts]` names them.
"""

from dynabarn.cli.bench import bench_main
from dynabarn.cli.demos import demos_main
from dynabarn.cli.export import export_main
from dynabarn.cli.render import render_main
from dynabarn.cli.replay import replay_main
from dynabarn.cli.ros import ros_main
from dynabarn.cli.run import run_main
from dynabarn.cli.teleop import teleop_main
from dynabarn.cli.train import train_main
from dynabarn.cli.worlds import worlds_main

__all__ = [
    "bench_main",
    "demos_main",
    "export_main",
    "render_main",
    "replay_main",
    "ros_main",
    "run_main",
    "teleop_main",
    "train_main",
    "worlds_main",
]
