"""Build the smallest ROS 2 Jazzy a navigation stack and the bridge need, from source,
outside the package: rclcpp and rclpy over Debian's Cyclone DDS, the message packages, tf2,
launch, the `ros2` command line and rosbag2 (`ros2 bag`, MCAP storage).

ROS 2 is not packaged for current Debian (no `rclpy` on PyPI or in Debian), but its
sources are public repositories and Debian packs what they build on (Cyclone DDS 0.10,
TinyXML2, spdlog, yaml-cpp, Eigen, console_bridge, pybind11, empy 3). The sources are one
release sync of Jazzy, `release-jazzy-20241223` of `ros2/ros2` (each repository at the
version that sync lists: no version skew between them), fetched by the user into one
folder (`--source`, or `ROS2_SRC=` for `make ros2-core`), e.g. with vcstool:

    vcs import ROS2_SRC < jazzy-core.repos      # python -m dynabarn.ros.ros2_build --repos
    make ros2-core ROS2_SRC=ROS2_SRC            # deps (root), then colcon

Each repository is a folder of ROS2_SRC named as the repository (`rclpy`, `geometry2`;
vcstool's nesting, ROS2_SRC/ros2/rclpy, is found too), its package versions checked
against the sync's before anything is built. colcon (from PyPI, in a virtual environment
over Debian's /usr/bin/python3, the interpreter rclpy is built for) builds the packages
`CORE_PACKAGES` need into the prefix (default `~/.cache/dynabarn/ros2`, or
`$DYNABARN_ROS2_WS`): `install/` (merged), `build/`, the build's log and
`dynabarn-ros2.json` (the sync, the packages, the sources' versions, seconds, size),
written last: a prefix without it is not finished. A second run with the same sources
finds that record and builds nothing.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from dynabarn.ros import colcon
from dynabarn.ros.colcon import colcon_build, read_marker

SYNC = "release-jazzy-20241223"
"""The release sync of `ros2/ros2` (its `ros2.repos` at this tag) every version below is from."""

REPOSITORIES: dict[str, tuple[str, str]] = {
    # name: (repository, version): the sync's tag; where a repository's own snapshot lacks
    # it, the same tree from its release repository (ros2-gbp/NAME-release, upstream/VERSION).
    "ament_cmake": ("ament/ament_cmake", "2.5.3"),
    "ament_index": ("ament/ament_index", "1.8.1"),
    "ament_lint": ("ament/ament_lint", "0.17.1"),
    "ament_package": ("ament/ament_package", "0.16.3"),
    "ament_cmake_ros": ("ros2/ament_cmake_ros", "0.12.0"),
    "class_loader": ("ros/class_loader", "2.7.0"),
    "common_interfaces": ("ros2/common_interfaces", "5.3.5"),
    "console_bridge_vendor": ("ros2/console_bridge_vendor", "1.7.1"),
    "eigen3_cmake_module": ("ros2/eigen3_cmake_module", "0.3.0"),
    "geometry2": ("ros2/geometry2", "0.36.7"),
    "keyboard_handler": ("ros-tooling/keyboard_handler", "0.3.1"),
    "launch": ("ros2/launch", "3.4.3"),
    "launch_ros": ("ros2/launch_ros", "0.26.6"),
    "libstatistics_collector": ("ros-tooling/libstatistics_collector", "1.7.4"),
    "libyaml_vendor": ("ros2/libyaml_vendor", "1.6.3"),
    "message_filters": ("ros2/message_filters", "4.11.2"),  # the sync: 4.11.3 (a fix to a Python test only)
    "orocos_kdl_vendor": ("ros2/orocos_kdl_vendor", "0.5.1"),
    "osrf_pycommon": ("osrf/osrf_pycommon", "2.1.5"),
    "pluginlib": ("ros/pluginlib", "5.4.2"),
    "pybind11_vendor": ("ros2/pybind11_vendor", "3.1.2"),
    "python_cmake_module": ("ros2/python_cmake_module", "0.11.1"),
    "rcl": ("ros2/rcl", "9.2.4"),
    "rcl_interfaces": ("ros2/rcl_interfaces", "2.0.2"),
    "rcl_logging": ("ros2/rcl_logging", "3.1.1"),
    "rclcpp": ("ros2/rclcpp", "28.1.6"),
    "rclpy": ("ros2/rclpy", "7.1.3"),
    "rcpputils": ("ros2/rcpputils", "2.11.1"),
    "rcutils": ("ros2/rcutils", "6.7.2"),
    "rmw": ("ros2/rmw", "7.3.1"),
    "rmw_cyclonedds": ("ros2/rmw_cyclonedds", "2.2.2"),
    "rmw_dds_common": ("ros2/rmw_dds_common", "3.1.0"),
    "rmw_implementation": ("ros2/rmw_implementation", "2.15.4"),
    "ros2_tracing": ("ros2/ros2_tracing", "8.2.3"),
    "rosbag2": ("ros2/rosbag2", "0.26.6"),
    "ros2cli": ("ros2/ros2cli", "0.32.2"),
    "ros_environment": ("ros/ros_environment", "4.2.1"),
    "rosidl": ("ros2/rosidl", "4.6.5"),
    "rosidl_core": ("ros2/rosidl_core", "0.2.0"),
    "rosidl_defaults": ("ros2/rosidl_defaults", "1.6.0"),
    "rosidl_dynamic_typesupport": ("ros2/rosidl_dynamic_typesupport", "0.1.2"),
    "rosidl_python": ("ros2/rosidl_python", "0.22.0"),
    "rosidl_runtime_py": ("ros2/rosidl_runtime_py", "0.13.1"),
    "rosidl_typesupport": ("ros2/rosidl_typesupport", "3.2.2"),
    "rpyutils": ("ros2/rpyutils", "0.4.1"),
    "spdlog_vendor": ("ros2/spdlog_vendor", "1.6.1"),
    "tinyxml2_vendor": ("ros2/tinyxml2_vendor", "0.9.1"),
    "unique_identifier_msgs": ("ros2/unique_identifier_msgs", "2.5.0"),
    "yaml_cpp_vendor": ("ros2/yaml_cpp_vendor", "9.0.1"),
}
"""Every repository the core is built from, with its version in the sync (`SYNC`)."""
DOWNLOADS = {
    # mcap_vendor's CMake downloads MCAP's C++ library (this tag's tarball) at build time.
    "mcap": colcon.Download(
        "foxglove/mcap",
        "releases/cpp/v1.3.0",
        content="mcap",
        version_file="cpp/mcap/include/mcap/types.hpp",
        version_text='#define MCAP_LIBRARY_VERSION "1.3.0"',
    ),
}
"""Sources a package's CMake would download, fetched with the repositories instead."""
_YAML_CPP_07 = (
    "Debian has yaml-cpp 0.7 and yaml_cpp_vendor asks for 0.8, else it clones 0.8 with vcstool while "
    "building (no network here); rosbag2, its only user in the core, builds and runs on 0.7"
)
EDITS = (
    colcon.SourceEdit(
        "yaml_cpp_vendor",
        "CMakeLists.txt",
        "find_package(yaml-cpp 0.8.0 QUIET",
        "find_package(yaml-cpp 0.7.0 QUIET",
        why=_YAML_CPP_07,
    ),
    colcon.SourceEdit(
        "yaml_cpp_vendor",
        "yaml_cpp_vendor-extras.cmake.in",
        "message(STATUS \"Setting yaml-cpp_DIR to: '${yaml-cpp_DIR}'\")",
        "message(STATUS \"Setting yaml-cpp_DIR to: '${yaml-cpp_DIR}'\")\n"
        "find_package(yaml-cpp REQUIRED)\n"
        "if(TARGET yaml-cpp AND NOT TARGET yaml-cpp::yaml-cpp)\n"
        "  add_library(yaml-cpp::yaml-cpp INTERFACE IMPORTED)\n"
        "  set_target_properties(yaml-cpp::yaml-cpp PROPERTIES INTERFACE_LINK_LIBRARIES yaml-cpp)\n"
        "endif()",
        why=_YAML_CPP_07 + " (0.7 names its target yaml-cpp; 0.8 yaml-cpp::yaml-cpp, which rosbag2 links)",
    ),
)
"""Changes to the fetched sources before they are built (`colcon.SourceEdit`)."""

CORE_PACKAGES = (
    "rclpy",
    "rclcpp",
    "rclcpp_lifecycle",
    "rclcpp_action",
    "rmw_cyclonedds_cpp",
    "tf2_ros",
    "tf2_ros_py",
    "tf2_geometry_msgs",
    "launch_ros",
    "ros2launch",
    "ros2topic",
    "ros2node",
    "ros2param",
    "ros2service",
    "ros2action",
    "ros2run",
    "ros2pkg",
    "ros2interface",
    "ros2lifecycle",
    "sensor_msgs",
    "nav_msgs",
    "geometry_msgs",
    "visualization_msgs",
    "std_srvs",
    "rosgraph_msgs",
    "tf2_msgs",
    "lifecycle_msgs",
    "pluginlib",
    "message_filters",
    # what Nav2 (`nav2_build`) takes from the core beyond the bridge's needs
    "diagnostic_msgs",
    "tf2_eigen",
    "tf2_sensor_msgs",
    "sensor_msgs_py",
    "ros_environment",
    # `ros2 bag record` / `play` against the bridge, in MCAP (rosbag2's default storage)
    "ros2bag",
    "rosbag2_storage_mcap",
)
"""What the bridge and a navigation stack use; colcon builds these and what they depend on."""
IGNORED = (
    "test_msgs",
    "ros2cli_test_interfaces",
    "test_tf2",
    "tf2_py",
    "tf2_kdl",
    "tf2_eigen_kdl",
    "tf2_bullet",
    "python_orocos_kdl_vendor",
    "rosbag2_test_common",
    "rosbag2_test_msgdefs",
)
"""Packages left out (test interfaces that `--packages-up-to` would follow; tf2's Python
KDL and Bullet bindings, which need libraries a navigation stack does not)."""
BUILD_DEPENDENCIES = [
    "cmake",
    "g++",
    "python3-dev",
    "python3-venv",
    "python3-numpy",
    "python3-empy",
    "python3-lark",
    "python3-catkin-pkg",
    "python3-psutil",
    "python3-yaml",
    "cyclonedds-dev",
    "libtinyxml2-dev",
    "libspdlog-dev",
    "libyaml-cpp-dev",
    "libyaml-dev",
    "pybind11-dev",
    "libconsole-bridge-dev",
    "libeigen3-dev",
    "libacl1-dev",
    "liborocos-kdl-dev",
    "libzstd-dev",  # rosbag2's zstd_vendor and liblz4_vendor take Debian's (MCAP's compression)
    "liblz4-dev",
]
"""Debian's packages for the build (`make ros2-deps` installs them)."""
WORKSPACE_ENV = "DYNABARN_ROS2_WS"
MARKER = "dynabarn-ros2.json"


def default_workspace() -> Path:
    return Path(os.environ.get(WORKSPACE_ENV) or Path.home() / ".cache" / "dynabarn" / "ros2")


def built(workspace: Path) -> dict | None:
    """The finished build's description, or None when the prefix has none."""
    return read_marker(workspace / MARKER)


def repos_file() -> str:
    """`REPOSITORIES` as a vcstool file (`vcs import ROS2_SRC < FILE`)."""
    return colcon.repos_file(REPOSITORIES, DOWNLOADS)


def find_sources(source: Path) -> dict[str, Path]:
    """Each repository's folder in `source`, checked against the sync (`colcon.find_sources`)."""
    return colcon.find_sources(source, REPOSITORIES, release=SYNC, module="ros2_build", downloads=DOWNLOADS)


def build(workspace: Path, source: Path, *, jobs: int = 2) -> dict:
    """The sources checked, then colcon (about 14 minutes on 2 cores); the description."""
    return colcon_build(
        workspace,
        source,
        find_sources(source),
        packages=CORE_PACKAGES,
        ignored=IGNORED,
        record={
            "sync": SYNC,
            "sources": {
                **{name: version for name, (_, version) in REPOSITORIES.items()},
                **{name: download.version for name, download in DOWNLOADS.items()},
            },
        },
        marker=MARKER,
        downloads=DOWNLOADS,
        edits=EDITS,
        what=f"ROS 2 ({SYNC}): about 14 minutes on 2 cores",
        jobs=jobs,
    )


def main(argv: list[str] | None = None) -> int:
    return colcon.build_command(
        argv,
        prog="python -m dynabarn.ros.ros2_build",
        description=f"Build the smallest ROS 2 Jazzy ({SYNC}: rclcpp, rclpy over Debian's Cyclone DDS, "
        "messages, tf2, launch, ros2cli) from fetched sources into a prefix outside the package "
        "(dependencies: `sudo make ros2-deps`).",
        source_variable="ROS2_SRC",
        workspace_env=WORKSPACE_ENV,
        default=default_workspace,
        default_shown="~/.cache/dynabarn/ros2",
        repositories=REPOSITORIES,
        downloads=DOWNLOADS,
        build=lambda workspace, source, args: build(workspace, source, jobs=args.jobs),
        label=f"ROS 2 {SYNC}",
    )


if __name__ == "__main__":
    sys.exit(main())
