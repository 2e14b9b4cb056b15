"""Build ROS 1's move_base (ros-planning/navigation) on a current Debian, outside the package.

ROS Noetic is end-of-life and not packaged for current Debian or Ubuntu, but Debian packs
ROS 1's core (ros_comm 1.15, tf2, pluginlib, actionlib, the message packages): every build
dependency of the navigation stack is a Debian package (`make ros-nav-deps`, as root). This
module puts the navigation sources at a pinned commit into a catkin workspace, leaves out
what a DynaBARN run does not use (amcl, map_server, fake_localization), and builds it with
Debian's catkin and Python:

    make ros-nav                                   # deps (root), sources by git, build
    python -m dynabarn.ros.nav_build --source DIR  # a local checkout instead of git

The workspace (default `~/.cache/dynabarn/ros_nav`, or `$DYNABARN_NAV_WS`) holds `src/`,
`build/`, `devel/`, the build's log and `dynabarn-nav.json` (commit, packages, when), which
is written last: a workspace without it is not finished. `dynabarn-ros --stack NAME` runs
the stacks of `dynabarn/ros/stacks/` from it.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.files import write_atomically

NAV_REPOSITORY = "https://github.com/ros-planning/navigation.git"
NAV_COMMIT = "9ad644198e132d0e950579a3bc72c29da46e60b0"
"""noetic-devel of 2023-03-04: move_base 1.17.3, the last Noetic release."""
LEFT_OUT = ("amcl", "map_server", "fake_localization", "navigation")
"""Not needed to navigate in a simulated odometry frame (and `navigation` is a metapackage
naming them)."""
WORKSPACE_ENV = "DYNABARN_NAV_WS"
MARKER = "dynabarn-nav.json"
BUILD_DEPENDENCIES = [
    "catkin",
    "python3-catkin-pkg",
    "ros-cmake-modules",
    "ros-message-generation",
    "ros-message-runtime",
    "cmake",
    "g++",
    "libroscpp-dev",
    "librosconsole-dev",
    "libtf2-dev",
    "libtf2-ros-dev",
    "libtf2-geometry-msgs-dev",
    "libtf2-sensor-msgs-dev",
    "pluginlib-dev",
    "libclass-loader-dev",
    "python3-dynamic-reconfigure",
    "libdynamic-reconfigure-config-init-mutex-dev",
    "liblaser-geometry-dev",
    "libangles-dev",
    "libactionlib-dev",
    "libactionlib-msgs-dev",
    "libmessage-filters-dev",
    "libmap-msgs-dev",
    "libmove-base-msgs-dev",
    "libnav-msgs-dev",
    "libgeometry-msgs-dev",
    "libsensor-msgs-dev",
    "libstd-msgs-dev",
    "libstd-srvs-dev",
    "libvisualization-msgs-dev",
    "libnetpbm-dev",
    "libeigen3-dev",
    "ros-actionlib-msgs",
    "ros-geometry-msgs",
    "ros-nav-msgs",
    "ros-sensor-msgs",
    "ros-std-msgs",
    "ros-visualization-msgs",
    "ros-map-msgs",
    "ros-move-base-msgs",
    "ros-tf2-msgs",
    "python3-tf2-ros",
]
"""Debian's packages for the build (`make ros-nav-deps` installs them)."""


def default_workspace() -> Path:
    return Path(os.environ.get(WORKSPACE_ENV) or Path.home() / ".cache" / "dynabarn" / "ros_nav")


def built(workspace: Path) -> dict | None:
    """The finished build's description, or None when the workspace has none."""
    return read_marker(workspace / MARKER)


def read_marker(path: Path) -> dict | None:
    """A finished build's description (`write_marker`'s), or None when there is none."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def run_logged(cmd: list[str], log, *, cwd: Path | None = None, env: dict | None = None) -> None:
    """cmd with its output into the open log file; one clear error naming the log if it fails."""
    log.write(f"$ {' '.join(cmd)}\n")
    log.flush()
    done = subprocess.run(cmd, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    if done.returncode:
        raise DynabarnError(f"{Path(cmd[0]).name} failed with status {done.returncode}: see {log.name}")


def debian_env() -> dict:
    """This environment with Debian's interpreter and tools first: a virtual environment's
    python would build the messages' Python for the wrong interpreter."""
    env = {**os.environ, "PATH": "/usr/bin:/bin:" + os.environ.get("PATH", "")}
    env.pop("VIRTUAL_ENV", None)
    env.pop("PYTHONPATH", None)
    return env


def checkout(repository: str, commit: str, dest: Path, local: Path | None, log) -> str:
    """The source tree at dest, copied from a local checkout (never written to) or fetched
    at `commit` with git; the commit it holds ('local' when it cannot be told)."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    if local is not None:
        shutil.copytree(local, dest, ignore=shutil.ignore_patterns(".git"))
        head = subprocess.run(["git", "-C", str(local), "rev-parse", "HEAD"], capture_output=True, text=True)
        return head.stdout.strip() if head.returncode == 0 else "local"
    if shutil.which("git") is None:
        raise DynabarnError("git is not installed: install it, or give a local checkout")
    run_logged(["git", "init", "-q", str(dest)], log)
    run_logged(["git", "-C", str(dest), "fetch", "-q", "--depth", "1", repository, commit], log)
    run_logged(["git", "-C", str(dest), "checkout", "-q", "FETCH_HEAD"], log)
    return commit


def _sources(workspace: Path, source: Path | None, log) -> str:
    """The navigation tree in workspace/src/navigation; its commit (or 'local')."""
    dest = workspace / "src" / "navigation"
    commit = checkout(NAV_REPOSITORY, NAV_COMMIT, dest, source, log)
    for name in LEFT_OUT:
        if (dest / name).is_dir():
            (dest / name / "CATKIN_IGNORE").write_text("left out by dynabarn.ros.nav_build\n")
    return commit


def build(workspace: Path, source: Path | None = None, *, jobs: int = 2) -> dict:
    """Sources, then `catkin_make` with Debian's Python first on PATH; the description.
    A `source` that is not the navigation stack is refused before anything is written."""
    if source is not None and not (source / "move_base" / "package.xml").is_file():
        raise DynabarnError(f"{source}: not a ros-planning/navigation checkout (no move_base/package.xml)")
    catkin_make = Path("/usr/bin/catkin_make")
    if not catkin_make.exists():
        raise DynabarnError(
            "Debian's catkin is not installed: `sudo make ros-nav-deps` (or apt-get install "
            + " ".join(BUILD_DEPENDENCIES[:3])
            + " ...)"
        )
    workspace.mkdir(parents=True, exist_ok=True)
    (workspace / MARKER).unlink(missing_ok=True)
    log_path = workspace / "build.log"
    t0 = time.monotonic()
    with log_path.open("w") as log:
        print(f"sources into {workspace / 'src'} (log: {log_path})", file=sys.stderr)
        commit = _sources(workspace, source, log)
        print(f"building with catkin_make -j{jobs} (about 6 minutes on 2 cores)", file=sys.stderr)
        run_logged(
            [
                str(catkin_make),
                "-C",  # catkin_make reads $PWD, not the working directory
                str(workspace),
                f"-j{jobs}",
                "-DCMAKE_BUILD_TYPE=Release",
                "-DPYTHON_EXECUTABLE=/usr/bin/python3",
                "-DCATKIN_ENABLE_TESTING=OFF",
            ],
            log,
            cwd=workspace,
            env=debian_env(),
        )
    if not (workspace / "devel" / "lib" / "move_base" / "move_base").exists():
        raise DynabarnError(f"the build ended without devel/lib/move_base/move_base: see {log_path}")
    return write_marker(
        workspace / MARKER,
        {"repository": NAV_REPOSITORY if source is None else str(source), "commit": commit, "left_out": list(LEFT_OUT)},
        t0,
    )


def write_marker(path: Path, info: dict, t0: float) -> dict:
    """A finished build's description (with when, and its seconds since t0), written last
    and whole: a workspace without it is not finished."""
    info = {
        **info,
        "built": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "seconds": round(time.monotonic() - t0, 1),
    }
    write_atomically(path, json.dumps(info, indent=2) + "\n")
    return info


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m dynabarn.ros.nav_build",
        description="Build ROS 1's navigation stack (move_base, DWA, navfn, costmap_2d) from source into a catkin "
        "workspace outside the package, against Debian's ROS 1 (dependencies: `sudo make ros-nav-deps`).",
    )
    parser.add_argument(
        "--workspace",
        type=Path,
        default=None,
        help=f"catkin workspace to build in (default: ${WORKSPACE_ENV} or ~/.cache/dynabarn/ros_nav)",
    )
    parser.add_argument(
        "--source",
        type=Path,
        default=None,
        help=f"a local ros-planning/navigation checkout (default: git fetch of {NAV_COMMIT[:7]}, noetic-devel)",
    )
    parser.add_argument("--jobs", type=int, default=2, help="parallel compile jobs (default: 2)")
    args = parser.parse_args(argv)
    workspace = (args.workspace or default_workspace()).expanduser().resolve()
    try:
        info = build(workspace, args.source.expanduser().resolve() if args.source else None, jobs=args.jobs)
    except (DynabarnError, OSError) as exc:  # a read-only or full disk: one line too
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"built navigation {info['commit'][:12]} in {info['seconds']:.0f} s: {workspace}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
