"""Build teb_local_planner (with costmap_converter, move_base_flex's core and g2o) into the
move_base workspace that `make ros-nav` built, on a current Debian.

teb_local_planner was never packaged by Debian, and neither was g2o, its optimiser. Every
other dependency is a Debian package (`make ros-teb-deps`, as root). What a current
system needs beyond the sources, and what this module does without touching them:

- g2o (a 2020 release, C++11, what ROS Noetic shipped) built with CMake into the
  workspace's `g2o/` prefix; teb's `FindG2O` finds it through `CMAKE_PREFIX_PATH`;
- shim headers for pluginlib 5.2, which removed the deprecated `class_list_macros.h` and
  `class_loader.h` (each includes its `.hpp` successor);
- `-DBOOST_BIND_GLOBAL_PLACEHOLDERS` with `boost/bind.hpp` included first (Boost 1.74 moved
  `_1` out of the global namespace; costmap_converter uses it without the header);
- teb's and costmap_converter's `-std=c++11` left out (their `COMPILER_SUPPORTS_CXX11`
  checks answered in advance): Debian's ROS headers need C++17, gcc 12's default.

move_base_flex: only the four packages teb needs (`mbf_abstract_core`, `mbf_costmap_core`,
`mbf_msgs`, `mbf_utility`); the rest is CATKIN_IGNOREd.

    make ros-teb                                   # deps (root), sources by git, build
    python -m dynabarn.ros.teb_build --sources DIR # DIR/{teb_local_planner,costmap_converter,
                                                   #      move_base_flex,g2o}: local checkouts

`dynabarn-teb.json` (commits, when) is written last: a workspace without it has no TEB.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.files import write_atomically
from dynabarn.ros.nav_build import built as nav_built
from dynabarn.ros.nav_build import checkout, debian_env, default_workspace, read_marker, run_logged, write_marker

MARKER = "dynabarn-teb.json"
G2O_MARKER = "dynabarn-g2o-commit"


@dataclass(frozen=True)
class Source:
    """One repository at a pinned commit and where it goes."""

    name: str  # the folder under --sources, and under the workspace
    repository: str
    commit: str
    why: str


SOURCES = (
    Source(
        "teb_local_planner",
        "https://github.com/rst-tu-dortmund/teb_local_planner.git",
        "b68c3288a0bca1d4b7c17c5972c2185b08d4cf09",
        "noetic-devel of 2024-01-06 (0.9.1)",
    ),
    Source(
        "costmap_converter",
        "https://github.com/rst-tu-dortmund/costmap_converter.git",
        "e8c1d2c8c8d5e34b1980062e28e4a4dc1817bade",
        "0.0.13, the release ROS Noetic shipped",
    ),
    Source(
        "move_base_flex",
        "https://github.com/magazino/move_base_flex.git",
        "43063b9577ea11a122f65b6067ac9c76dfee92f0",
        "the noetic branch (0.4.0)",
    ),
    Source(
        "g2o",
        "https://github.com/RainerKuemmerle/g2o.git",
        "1b89597b4e495bef5447c5b8001f5f93ccf32ec4",
        "20201223_git, C++11 (ROS Noetic's libg2o was 2020.5.29)",
    ),
)
MBF_KEPT = ("mbf_abstract_core", "mbf_costmap_core", "mbf_msgs", "mbf_utility")
BUILD_DEPENDENCIES = [
    "libsuitesparse-dev",
    "libboost-graph-dev",
    "libinteractive-markers-dev",
    "libtf2-eigen-dev",
    "libtf-dev",
    "libcv-bridge-dev",
    "libopencv-dev",
    "ros-tf2-msgs",
]
"""Debian's packages for the build beyond move_base's (`make ros-teb-deps` installs them)."""
SHIMS = {
    "pluginlib/class_list_macros.h": "#include <pluginlib/class_list_macros.hpp>\n",
    "pluginlib/class_loader.h": "#include <pluginlib/class_loader.hpp>\n",
}


def built(workspace: Path) -> dict | None:
    """The finished TEB build's description, or None."""
    return read_marker(workspace / MARKER)


def _g2o(workspace: Path, commit: str, log, jobs: int) -> Path:
    """g2o built and installed into workspace/g2o (kept when an earlier run installed this
    commit there: a failed catkin_make run again does not rebuild it); the prefix."""
    prefix, build_dir = workspace / "g2o", workspace / "g2o_build"
    installed = prefix / G2O_MARKER
    if commit != "local" and installed.is_file() and installed.read_text().strip() == commit:
        print(f"g2o {commit[:7]} already installed in {prefix}", file=sys.stderr)
        return prefix
    installed.unlink(missing_ok=True)
    shutil.rmtree(build_dir, ignore_errors=True)
    cmake = [
        "cmake",
        "-S",
        str(workspace / "g2o_src"),
        "-B",
        str(build_dir),
        "-DCMAKE_BUILD_TYPE=Release",
        f"-DCMAKE_INSTALL_PREFIX={prefix}",
        "-DG2O_BUILD_APPS=OFF",
        # The examples hold g2o_incremental, which teb's FindG2O requires (ROS's libg2o had it).
        "-DG2O_BUILD_EXAMPLES=ON",
        "-DG2O_USE_OPENGL=OFF",
        "-DBUILD_WITH_MARCH_NATIVE=OFF",  # the workspace may be copied to another CPU
        "-DBUILD_UNITTESTS=OFF",
    ]
    run_logged(cmake, log, env=debian_env())
    run_logged(["cmake", "--build", str(build_dir), "-j", str(jobs), "--target", "install"], log, env=debian_env())
    write_atomically(installed, commit + "\n")
    return prefix


def build(workspace: Path, sources: Path | None = None, *, jobs: int = 2) -> dict:
    """g2o, the sources into workspace/src, then catkin_make over the whole workspace."""
    if nav_built(workspace) is None:
        raise DynabarnError(f"{workspace} has no finished move_base build: run `make ros-nav` first")
    if sources is not None:
        missing = [s.name for s in SOURCES if not (sources / s.name).is_dir()]
        if missing:
            raise DynabarnError(f"{sources}: no {', '.join(missing)} folder (the checkouts to build)")
    (workspace / MARKER).unlink(missing_ok=True)
    log_path = workspace / "teb_build.log"
    t0 = time.monotonic()
    commits = {}
    with log_path.open("w") as log:
        print(f"sources into {workspace} (log: {log_path})", file=sys.stderr)
        for s in SOURCES:
            dest = workspace / ("g2o_src" if s.name == "g2o" else f"src/{s.name}")
            commits[s.name] = checkout(s.repository, s.commit, dest, None if sources is None else sources / s.name, log)
        for package in (workspace / "src" / "move_base_flex").iterdir():
            if package.is_dir() and package.name not in MBF_KEPT:
                (package / "CATKIN_IGNORE").write_text("left out by dynabarn.ros.teb_build\n")
        shims = workspace / "shims"
        for rel, text in SHIMS.items():
            (shims / rel).parent.mkdir(parents=True, exist_ok=True)
            (shims / rel).write_text(text)
        print(f"building g2o (about 8 minutes on {jobs} cores)", file=sys.stderr)
        prefix = _g2o(workspace, commits["g2o"], log, jobs)
        print("building teb_local_planner and the rest with catkin_make (about 15 minutes)", file=sys.stderr)
        run_logged(
            [
                "/usr/bin/catkin_make",
                "-C",
                str(workspace),
                f"-j{jobs}",
                "-DCMAKE_BUILD_TYPE=Release",
                "-DPYTHON_EXECUTABLE=/usr/bin/python3",
                "-DCATKIN_ENABLE_TESTING=OFF",
                f"-DCMAKE_PREFIX_PATH={prefix}",
                # FindG2O would take include/g2o (where g2o's folders are); the sources include <g2o/...>.
                f"-DG2O_INCLUDE_DIR={prefix / 'include'}",
                "-DCOMPILER_SUPPORTS_CXX11=0",  # keeps gcc's C++17: Debian's ROS headers need it
                "-DCOMPILER_SUPPORTS_CXX0X=0",
                # Boost's placeholders global again, as before 1.73 (sources use _1 without the header).
                f"-DCMAKE_CXX_FLAGS=-isystem {shims} -DBOOST_BIND_GLOBAL_PLACEHOLDERS -include boost/bind.hpp",
            ],
            log,
            cwd=workspace,
            env=debian_env(),
        )
    plugin = workspace / "devel" / "lib" / "libteb_local_planner.so"
    if not plugin.exists():
        raise DynabarnError(f"the build ended without {plugin.relative_to(workspace)}: see {log_path}")
    sources_used = {s.name: {"repository": s.repository, "commit": commits[s.name]} for s in SOURCES}
    return write_marker(workspace / MARKER, {"sources": sources_used}, t0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m dynabarn.ros.teb_build",
        description="Build teb_local_planner, costmap_converter, move_base_flex's core and g2o from source into "
        "the move_base workspace of `make ros-nav` (dependencies: `sudo make ros-teb-deps`).",
    )
    parser.add_argument(
        "--workspace",
        type=Path,
        default=None,
        help="the catkin workspace of `make ros-nav` (default: $DYNABARN_NAV_WS or ~/.cache/dynabarn/ros_nav)",
    )
    parser.add_argument(
        "--sources",
        type=Path,
        default=None,
        help="a folder of local checkouts named " + ", ".join(s.name for s in SOURCES) + " (default: git fetch of "
        "each pinned commit: " + "; ".join(f"{s.name} {s.commit[:7]}, {s.why}" for s in SOURCES) + ")",
    )
    parser.add_argument("--jobs", type=int, default=2, help="parallel compile jobs (default: 2)")
    args = parser.parse_args(argv)
    workspace = (args.workspace or default_workspace()).expanduser().resolve()
    try:
        info = build(workspace, args.sources.expanduser().resolve() if args.sources else None, jobs=args.jobs)
    except (DynabarnError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"built teb_local_planner {info['sources']['teb_local_planner']['commit'][:12]} in {info['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
