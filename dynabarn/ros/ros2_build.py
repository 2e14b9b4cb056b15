"""Build the smallest ROS 2 Jazzy a navigation stack and the bridge need, from source,
outside the package: rclcpp and rclpy over Debian's Cyclone DDS, the message packages, tf2,
launch and the `ros2` command line.

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

import argparse
import hashlib
import os
import re
import shlex
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.ros.nav_build import debian_env, read_marker, run_logged, write_marker

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
]
"""Debian's packages for the build (`make ros2-deps` installs them)."""
COLCON = "colcon-common-extensions==0.3.0"
"""colcon from PyPI (Debian has none), in the prefix's own virtual environment."""
WORKSPACE_ENV = "DYNABARN_ROS2_WS"
MARKER = "dynabarn-ros2.json"


def default_workspace() -> Path:
    return Path(os.environ.get(WORKSPACE_ENV) or Path.home() / ".cache" / "dynabarn" / "ros2")


def built(workspace: Path) -> dict | None:
    """The finished build's description, or None when the prefix has none."""
    return read_marker(workspace / MARKER)


def setup_script(workspace: Path) -> Path:
    """The prefix's `setup.bash`, which a stack's shell sources."""
    return workspace / "install" / "setup.bash"


def repos_file(repositories: dict[str, tuple[str, str]] = REPOSITORIES) -> str:
    """The repositories as a vcstool file (`vcs import SRC < FILE`)."""
    lines = ["repositories:"]
    for name, (repository, version) in repositories.items():
        url = f"https://github.com/{repository}.git"
        lines += [f"  {name}:", "    type: git", f"    url: {url}", f"    version: {version}"]
    return "\n".join(lines) + "\n"


def _package_versions(tree: Path) -> dict[str, str]:
    """name -> version of every package.xml under `tree` (the first folder down that has one)."""
    found = {}
    for xml in sorted(tree.rglob("package.xml")):
        text = xml.read_text(errors="replace")
        name, version = re.search(r"<name>\s*([^<\s]+)", text), re.search(r"<version>\s*([^<\s]+)", text)
        if name and version:
            found[name.group(1)] = version.group(1)
    return found


def find_sources(
    source: Path,
    repositories: dict[str, tuple[str, str]] = REPOSITORIES,
    *,
    release: str = SYNC,
    module: str = "ros2_build",
) -> dict[str, Path]:
    """Each repository's folder in `source` (by its name, or vcstool's ORG/NAME), checked:
    every one present, each of its packages at the release's version. One line naming what
    is missing or other."""
    if not source.is_dir():
        raise DynabarnError(f"{source}: no such folder (fetch the sources: python -m dynabarn.ros.{module} --repos)")
    folders, other, missing = {}, [], []
    for name, (repository, version) in repositories.items():
        folder = next((p for p in (source / name, source / repository) if p.is_dir()), None)
        versions = _package_versions(folder) if folder is not None else {}
        if not versions:
            missing.append(name)
            continue
        found = sorted({v for v in versions.values() if v != version})
        if found:
            other.append(f"{name} ({', '.join(found)}, not {version})")
        folders[name] = folder
    if other or missing:
        shown = other[:4] + ([f"{len(missing)} missing ({', '.join(missing[:4])}{', ...' if len(missing) > 4 else ''})"]
                             if missing else [])  # fmt: skip
        raise DynabarnError(f"{source}: not the sources of {release}: {'; '.join(shown)}")
    return folders


def sources_digest(folders: dict[str, Path]) -> str:
    """sha256 over every source file's path and bytes: what decides whether a build is current."""
    digest = hashlib.sha256()
    for name, folder in sorted(folders.items()):
        for path in sorted(p for p in folder.rglob("*") if p.is_file()):
            digest.update(f"{name}/{path.relative_to(folder)}\0".encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


def _colcon(workspace: Path, log) -> Path:
    """colcon in the prefix's virtual environment over Debian's Python (made once)."""
    venv = workspace / "tools"
    colcon = venv / "bin" / "colcon"
    if not colcon.exists():
        run_logged(["/usr/bin/python3", "-m", "venv", "--system-site-packages", str(venv)], log, env=debian_env())
        (venv / "COLCON_IGNORE").write_text("")  # colcon never takes the tools for packages
        run_logged([str(venv / "bin" / "pip"), "install", "-q", COLCON], log, env=debian_env())
    return colcon


def _folder_size(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file() and not p.is_symlink())


def colcon_build(
    workspace: Path,
    source: Path,
    folders: dict[str, Path],
    *,
    packages: tuple[str, ...],
    ignored: tuple[str, ...],
    record: dict,
    marker: str,
    what: str,
    jobs: int = 2,
    underlay: Path | None = None,
    cmake_args: tuple[str, ...] = (),
    package_cmake_args: dict[str, tuple[str, ...]] | None = None,
) -> dict:
    """colcon over the checked sources `folders` of `source` into `workspace` (`install/`
    merged, `build/`, `build.log`, the marker written last), over the prefix `underlay`
    when given (its `setup.bash` sourced first), `package_cmake_args` {package: CMake
    arguments of its own} built alone after the rest; `record` plus the packages, the sources'
    digest, size and seconds, with `rebuilt`. Nothing is built when the marker names the
    same sources, holds every package asked for and was built with the same arguments."""
    if not Path("/usr/bin/python3").exists() or shutil.which("cmake") is None:
        raise DynabarnError("Debian's build tools are missing: `sudo make ros2-deps`")
    package_cmake_args = package_cmake_args or {}
    digest = sources_digest(folders)
    done = read_marker(workspace / marker)
    if (
        done is not None
        and done.get("sources_sha256") == digest
        and set(packages) <= set(done.get("packages", ()))
        and done.get("cmake_args", []) == list(cmake_args)
        and done.get("package_cmake_args", {}) == {k: list(v) for k, v in package_cmake_args.items()}
        and setup_script(workspace).is_file()
    ):
        return {**done, "rebuilt": False}
    workspace.mkdir(parents=True, exist_ok=True)
    (workspace / marker).unlink(missing_ok=True)
    src = workspace / "src"
    if src.exists():
        shutil.rmtree(src)
    shutil.copytree(source, src, symlinks=True, ignore=shutil.ignore_patterns(".git"))
    for package in ignored:
        for xml in src.rglob("package.xml"):
            if f"<name>{package}</name>" in xml.read_text(errors="replace"):
                (xml.parent / "COLCON_IGNORE").write_text("left out by dynabarn.ros\n")
    log_path = workspace / "build.log"
    t0 = time.monotonic()
    with log_path.open("w") as log:
        colcon = _colcon(underlay or workspace, log)  # an overlay uses its underlay's colcon
        print(f"building {what} with colcon, {jobs} workers (log: {log_path})", file=sys.stderr)
        env = {**debian_env(), "PATH": f"{colcon.parent}:/usr/bin:/bin", "MAKEFLAGS": f"-j{jobs}"}
        common = [
            str(colcon), "build", "--base-paths", str(src), "--build-base", str(workspace / "build"),
            "--install-base", str(workspace / "install"), "--merge-install", "--parallel-workers", str(jobs),
            "--event-handlers", "console_direct-",
        ]  # fmt: skip
        flags = ["-DBUILD_TESTING=OFF", "-DTRACETOOLS_DISABLED=ON", "-DCMAKE_BUILD_TYPE=Release",
                 "-DPython3_EXECUTABLE=/usr/bin/python3", *cmake_args]  # fmt: skip
        # Everything but the packages with flags of their own, then each of those alone.
        skip = ["--packages-skip", *package_cmake_args] if package_cmake_args else []
        runs = [[*common, "--packages-up-to", *packages, *skip, "--cmake-args", *flags]]
        runs += [[*common, "--packages-select", name, "--cmake-args", *flags, *extra]
                 for name, extra in package_cmake_args.items()]  # fmt: skip
        for command in runs:
            if underlay is not None:  # the underlay's environment (its packages, libraries) for colcon
                line = f"source {shlex.quote(str(setup_script(underlay)))} && exec {shlex.join(command)}"
                command = ["bash", "-c", line]
            run_logged(command, log, cwd=workspace, env=env)
    if not setup_script(workspace).is_file():
        raise DynabarnError(f"the build ended without {setup_script(workspace)}: see {log_path}")
    share = workspace / "install" / "share"
    info = {
        **record,
        "sources_sha256": digest,
        "packages": sorted(p.name for p in share.iterdir() if (p / "package.xml").is_file()),
        "install_bytes": _folder_size(workspace / "install"),
        **({"cmake_args": list(cmake_args)} if cmake_args else {}),
        **({"package_cmake_args": {k: list(v) for k, v in package_cmake_args.items()}} if package_cmake_args else {}),
        "jobs": jobs,
    }
    return {**write_marker(workspace / marker, info, t0), "rebuilt": True}


def build(workspace: Path, source: Path, *, jobs: int = 2) -> dict:
    """The sources checked, then colcon (about 11 minutes on 2 cores); the description."""
    return colcon_build(
        workspace,
        source,
        find_sources(source),
        packages=CORE_PACKAGES,
        ignored=IGNORED,
        record={"sync": SYNC, "sources": {name: version for name, (_, version) in REPOSITORIES.items()}},
        marker=MARKER,
        what=f"ROS 2 ({SYNC}): about 11 minutes on 2 cores",
        jobs=jobs,
    )


def build_command(
    argv: list[str] | None,
    *,
    prog: str,
    description: str,
    source_variable: str,
    workspace_env: str,
    default: Callable[[], Path],
    repositories: dict[str, tuple[str, str]],
    build: Callable[[Path, Path, argparse.Namespace], dict],
    label: str,
    add_arguments: Callable[[argparse.ArgumentParser], None] | None = None,
) -> int:
    """The command line of a colcon build of ours (`ros2_build`, `nav2_build`): --source,
    --workspace, --jobs, --repos, and what `add_arguments` adds; `build(workspace, source,
    args)` runs it. One line and exit 2 for bad input, a read-only or a full disk."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument(
        "--source", type=Path, default=None, help=f"the folder of fetched repositories ({source_variable})"
    )
    parser.add_argument(
        "--workspace",
        type=Path,
        default=None,
        help=f"prefix to build in (default: ${workspace_env} or {str(default()).replace(str(Path.home()), '~')})",
    )
    if add_arguments is not None:
        add_arguments(parser)
    parser.add_argument("--jobs", type=int, default=2, help="packages built at once, and compile jobs (default: 2)")
    parser.add_argument("--repos", action="store_true", help="print the repositories and versions as a vcstool file")
    args = parser.parse_args(argv)
    if args.repos:
        print(repos_file(repositories), end="")
        return 0
    if args.source is None:
        parser.error(f"--source ({source_variable}) is required: the folder of fetched repositories (see --repos)")
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    workspace = (args.workspace or default()).expanduser().resolve()
    try:
        info = build(workspace, args.source.expanduser().resolve(), args)
    except (DynabarnError, OSError) as exc:  # a read-only or full disk: one line too
        print(f"error: {exc}", file=sys.stderr)
        return 2
    what = f"built in {info['seconds']:.0f} s" if info["rebuilt"] else "already built from these sources"
    print(f"{label}: {len(info['packages'])} packages, {info['install_bytes'] / 1e6:.0f} MB, {what}: {workspace}")
    return 0


def main(argv: list[str] | None = None) -> int:
    return build_command(
        argv,
        prog="python -m dynabarn.ros.ros2_build",
        description=f"Build the smallest ROS 2 Jazzy ({SYNC}: rclcpp, rclpy over Debian's Cyclone DDS, "
        "messages, tf2, launch, ros2cli) from fetched sources into a prefix outside the package "
        "(dependencies: `sudo make ros2-deps`).",
        source_variable="ROS2_SRC",
        workspace_env=WORKSPACE_ENV,
        default=default_workspace,
        repositories=REPOSITORIES,
        build=lambda workspace, source, args: build(workspace, source, jobs=args.jobs),
        label=f"ROS 2 {SYNC}",
    )


if __name__ == "__main__":
    sys.exit(main())
