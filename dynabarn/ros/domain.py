"""What stands for ROS 1's master on ROS 2: a DDS domain of the bridge's own
(`ROS_DOMAIN_ID`, claimed by a lock so that parallel bridges never share one), discovery
kept on this machine, and the environment of the ROS 2 prefix `make ros2-core` built
(`ros2_build`), in which the bridge node and the stack run."""

from __future__ import annotations

import fcntl
import functools
import os
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from dynabarn.errors import NotInstalledHere

PREFIX_VARIABLES = ("AMENT", "COLCON", "ROS", "PYTHONPATH", "LD_LIBRARY_PATH", "CMAKE_PREFIX", "PATH")
"""The variables of a prefix's `setup.bash` the node and the stack take (PATH: `ros2`)."""
DOMAINS = range(1, 102)
"""The domain ids a bridge may claim (0, the default, is left to a user's own nodes; 101 is
the last whose ports stay below the ephemeral range)."""


@functools.cache
def prefix_env(setup: Path) -> dict[str, str]:
    """The variables `setup.bash` of a ROS 2 prefix sets (read once per process)."""
    done = subprocess.run(
        ["bash", "-c", 'source "$1" >/dev/null 2>&1 && env -0', "_", str(setup)],
        capture_output=True,
        env={"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/")},
        timeout=60,
    )
    if done.returncode:
        raise NotInstalledHere(f"{setup} could not be sourced", "make ros2-core ROS2_SRC=<folder>")
    pairs = (item.split("=", 1) for item in done.stdout.decode().split("\0") if "=" in item)
    return {k: v for k, v in pairs if k.startswith(PREFIX_VARIABLES)}


def built_setup(workspace: Path | None = None) -> Path:
    """The `setup.bash` of a finished `make ros2-core` build in `workspace` (default: the
    prefix's default); one clear line naming the command when there is none."""
    from dynabarn.ros.colcon import setup_script
    from dynabarn.ros.ros2_build import built, default_workspace

    workspace = workspace or default_workspace()
    if built(workspace) is None or not setup_script(workspace).is_file():
        raise NotInstalledHere(
            f"no ROS 2 built in {workspace}: `make ros2-core ROS2_SRC=<folder of the fetched repositories>`",
            "make ros2-core ROS2_SRC=<folder>",
        )
    return setup_script(workspace)


@dataclass
class Ros2Domain:
    """A DDS domain of the bridge's own in the ROS 2 prefix's environment (`close` frees it)."""

    domain: int
    setup: Path
    _lock: int | None = None

    @classmethod
    def start(cls, workspace: Path | None = None, overlay: Path | None = None) -> Ros2Domain:
        """A free domain in the core's environment, or in `overlay` (the `setup.bash` of a
        prefix built over the core, e.g. Nav2's, whose messages the bridge then imports)."""
        setup = overlay or built_setup(workspace)
        for domain in DOMAINS:
            fd = os.open(Path(tempfile.gettempdir()) / f"dynabarn-ros2-domain-{domain}.lock", os.O_RDWR | os.O_CREAT)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                continue
            return cls(domain, setup, fd)
        raise NotInstalledHere(f"every ROS 2 domain of {DOMAINS.start}..{DOMAINS.stop - 1} is in use here")

    @property
    def uri(self) -> str:
        """How a user reaches the bridge's graph (`ROS_DOMAIN_ID=N ros2 topic list`)."""
        return f"ROS_DOMAIN_ID={self.domain}"

    def env(self) -> dict[str, str]:
        prefix = prefix_env(self.setup)
        return {
            **os.environ,
            **prefix,
            "PATH": os.pathsep.join(p for p in (prefix.get("PATH"), os.environ.get("PATH")) if p),
            "ROS_DOMAIN_ID": str(self.domain),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",  # nothing leaves this machine
            "RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp",
        }

    def close(self) -> None:
        if self._lock is not None:
            os.close(self._lock)  # the lock goes with it
            self._lock = None
