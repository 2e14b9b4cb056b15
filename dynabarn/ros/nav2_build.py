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
from dynabarn.ros import ros2_build

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
    return ros2_build.read_marker(workspace / MARKER)


def find_sources(source: Path) -> dict[str, Path]:
    """Each repository's folder in `source`, checked as the core's are (`ros2_build.find_sources`)."""
    return ros2_build.find_sources(source, REPOSITORIES, release=f"Nav2 {NAV2_VERSION}", module="nav2_build")


def build(workspace: Path, source: Path, core: Path, *, jobs: int = 2) -> dict:
    """The sources checked, the core found, then colcon over it; the description."""
    folders = find_sources(source)
    if ros2_build.built(core) is None:
        raise DynabarnError(f"the ROS 2 core is not built in {core}: make ros2-core ROS2_SRC=<folder>")
    return ros2_build.colcon_build(
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
    parser = argparse.ArgumentParser(
        prog="python -m dynabarn.ros.nav2_build",
        description=f"Build Nav2 {NAV2_VERSION} (controller server with DWB and MPPI, planner server with NavFn, "
        "costmap_2d, lifecycle manager, BT navigator) from fetched sources, over the ROS 2 core "
        "(`make ros2-core`), into a prefix outside the package (dependencies: `sudo make nav2-deps`).",
    )
    parser.add_argument("--source", type=Path, default=None, help="the folder of fetched repositories (NAV2_SRC)")
    parser.add_argument(
        "--workspace",
        type=Path,
        default=None,
        help=f"prefix to build in (default: ${WORKSPACE_ENV} or ~/.cache/dynabarn/nav2)",
    )
    parser.add_argument(
        "--core",
        type=Path,
        default=None,
        help=f"the ROS 2 core's prefix (default: ${ros2_build.WORKSPACE_ENV} or ~/.cache/dynabarn/ros2)",
    )
    parser.add_argument("--jobs", type=int, default=2, help="packages built at once, and compile jobs (default: 2)")
    parser.add_argument("--repos", action="store_true", help="print the repositories and versions as a vcstool file")
    args = parser.parse_args(argv)
    if args.repos:
        print(ros2_build.repos_file(REPOSITORIES), end="")
        return 0
    if args.source is None:
        parser.error("--source (NAV2_SRC) is required: the folder of fetched repositories (see --repos)")
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    workspace = (args.workspace or default_workspace()).expanduser().resolve()
    core = (args.core or ros2_build.default_workspace()).expanduser().resolve()
    try:
        info = build(workspace, args.source.expanduser().resolve(), core, jobs=args.jobs)
    except (DynabarnError, OSError) as exc:  # a read-only or full disk: one line too
        print(f"error: {exc}", file=sys.stderr)
        return 2
    what = f"built in {info['seconds']:.0f} s" if info["rebuilt"] else "already built from these sources"
    size = f"{len(info['packages'])} packages, {info['install_bytes'] / 1e6:.0f} MB"
    print(f"Nav2 {NAV2_VERSION}: {size}, {what}: {workspace}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
