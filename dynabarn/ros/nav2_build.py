"""Build what a Nav2 local-planning run needs, from source, as an overlay on the ROS 2 core
(`ros2_build`): the controller server with DWB and MPPI, the planner server with NavFn,
costmap_2d, the lifecycle manager, the BT navigator (which serves `navigate_to_pose`) and the
behaviour server (the recoveries of Nav2's default behaviour tree).

Nav2 1.3.4 (its `jazzy` release of 2024-12-13) is the one that matches the core's sync; the
packages it needs beyond the core come from their Jazzy releases (where a repository's own
snapshot lacks the tag, the same tree from its release repository, ros2-gbp/NAME-release,
`upstream/VERSION`). The user fetches them into one folder (`--source`, or `NAV2_SRC=` for
`make nav2`), e.g. with vcstool:

    python -m dynabarn.ros.nav2_build --repos > nav2.repos && vcs import NAV2_SRC < nav2.repos
    make nav2 NAV2_SRC=NAV2_SRC      # Debian's dependencies (root), then colcon

The overlay (default `~/.cache/dynabarn/nav2`, or `$DYNABARN_NAV2_WS`) holds `install/`,
`build/`, the log and `dynabarn-nav2.json` (versions, packages, seconds, size), written
last. A second run with the same sources builds nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.ros import colcon, ros2_build

NAV2_VERSION = "1.3.4"
REPOSITORIES: dict[str, tuple[str, str]] = {
    "navigation2": ("ros-navigation/navigation2", NAV2_VERSION),
    "BehaviorTree.CPP": ("BehaviorTree/BehaviorTree.CPP", "4.6.2"),
    "laser_geometry": ("ros-perception/laser_geometry", "2.7.0"),
    "bond_core": ("ros/bond_core", "4.1.0"),
    "diagnostics": ("ros/diagnostics", "4.2.1"),
    "angles": ("ros/angles", "1.16.0"),
    "geographic_info": ("ros-geographic-info/geographic_info", "1.0.6"),
    "navigation_msgs": ("ros-planning/navigation_msgs", "2.4.1"),
}
"""Every repository the overlay is built from, at its Jazzy release of the core's time."""

PACKAGES = (
    "nav2_controller",
    "dwb_core",
    "dwb_critics",
    "dwb_plugins",
    "nav2_mppi_controller",
    "nav2_planner",
    "nav2_navfn_planner",
    "nav2_costmap_2d",
    "nav2_lifecycle_manager",
    "nav2_bt_navigator",
    "nav2_behaviors",
)
"""What a local-planning run starts (the behaviour server: the recoveries of Nav2's default
tree); colcon builds these and what they depend on."""
IGNORED = ("geodesy", "diagnostic_aggregator", "diagnostic_common_diagnostics", "self_test", "test_bond", "bondpy")
"""Packages of the fetched repositories a run never loads (and test packages)."""
PACKAGE_CMAKE_ARGS = {
    # MPPI turns on xtensor's SIMD (xsimd) and builds with -ffast-math; with Debian's xsimd
    # 8.1.0, xt::sin and xt::cos are then wrong (errors up to 2 in a test of 2000 x 56 angles
    # against std::sin, std::cos: the same code without xsimd, or without -ffast-math, is
    # right), and MPPI's rollouts turn the Jackal around: it crept backwards, away from the
    # goal. Undefined after MPPI's own definitions: xtensor's plain loops, the same maths.
    "nav2_mppi_controller": (
        "-DCMAKE_CXX_FLAGS=-Wno-error=null-dereference -UXTENSOR_USE_XSIMD -UXTENSOR_ENABLE_XSIMD",
    ),
}
CMAKE_ARGS = (
    "-DBTCPP_GROOT_INTERFACE=OFF",  # ZeroMQ for the Groot monitor: not used here
    "-DBTCPP_SQLITE_LOGGING=OFF",
    "-DBTCPP_EXAMPLES=OFF",
    "-DBTCPP_UNIT_TESTS=OFF",
    # Nav2 builds with -Werror -Wnull-dereference; GCC 12 finds a null dereference in Debian's
    # xtensor 0.24.3 (xreducer.hpp, reached by MPPI) that is a warning, not Nav2's error.
    "-DCMAKE_CXX_FLAGS=-Wno-error=null-dereference",
)
BUILD_DEPENDENCIES = ["xtensor-dev", "libxsimd-dev", "libomp-dev", "libbenchmark-dev", "uuid-dev", "libsqlite3-dev"]
"""Debian's packages Nav2 needs beyond the core's (`make nav2-deps`): MPPI's tensors and
OpenMP, bondcpp's UUIDs, BehaviorTree.CPP's logger."""
WORKSPACE_ENV = "DYNABARN_NAV2_WS"
MARKER = "dynabarn-nav2.json"


def default_workspace() -> Path:
    return Path(os.environ.get(WORKSPACE_ENV) or Path.home() / ".cache" / "dynabarn" / "nav2")


def built(workspace: Path) -> dict | None:
    """The finished overlay's description, or None when there is none."""
    return colcon.read_marker(workspace / MARKER)


def find_sources(source: Path) -> dict[str, Path]:
    """Each repository's folder in `source`, checked against its release (`colcon.find_sources`)."""
    return colcon.find_sources(source, REPOSITORIES, release=f"Nav2 {NAV2_VERSION}", module="nav2_build")


def build(workspace: Path, source: Path, core: Path, *, jobs: int = 2) -> dict:
    """The sources checked, the core found, then colcon over it; the description."""
    folders = find_sources(source)
    if ros2_build.built(core) is None:
        raise DynabarnError(f"the ROS 2 core is not built in {core}: make ros2-core ROS2_SRC=<folder>")
    return colcon.colcon_build(
        workspace,
        source,
        folders,
        packages=PACKAGES,
        ignored=IGNORED,
        record={
            "nav2": NAV2_VERSION,
            "sources": {name: version for name, (_, version) in REPOSITORIES.items()},
            "core": str(core),
        },
        marker=MARKER,
        what=f"Nav2 {NAV2_VERSION} over {core}: about 16 minutes on 2 cores",
        jobs=jobs,
        underlay=core,
        cmake_args=CMAKE_ARGS,
        package_cmake_args=PACKAGE_CMAKE_ARGS,
    )


def main(argv: list[str] | None = None) -> int:
    def core_argument(parser: argparse.ArgumentParser) -> None:
        parser.add_argument(
            "--core",
            type=Path,
            default=None,
            help=f"the ROS 2 core's prefix (default: ${ros2_build.WORKSPACE_ENV} or ~/.cache/dynabarn/ros2)",
        )

    def run(workspace: Path, source: Path, args: argparse.Namespace) -> dict:
        core = (args.core or ros2_build.default_workspace()).expanduser().resolve()
        return build(workspace, source, core, jobs=args.jobs)

    return colcon.build_command(
        argv,
        prog="python -m dynabarn.ros.nav2_build",
        description=f"Build Nav2 {NAV2_VERSION} (controller server with DWB and MPPI, planner server with NavFn, "
        "costmap_2d, lifecycle manager, BT navigator, behaviour server) from fetched sources, over the ROS 2 "
        "core (`make ros2-core`), into a prefix outside the package (dependencies: `sudo make nav2-deps`).",
        source_variable="NAV2_SRC",
        workspace_env=WORKSPACE_ENV,
        default=default_workspace,
        default_shown="~/.cache/dynabarn/nav2",
        repositories=REPOSITORIES,
        build=run,
        label=f"Nav2 {NAV2_VERSION}",
        add_arguments=core_argument,
    )


if __name__ == "__main__":
    sys.exit(main())
