"""How the bridge meets a ROS stack (`BridgeConfig`: lockstep or paced, the boot, the stack
to launch, ROS 1 or 2), the bridge node's topics (what `--remap` may rename), and the
Python that runs the node."""

from __future__ import annotations

import functools
import os
import shlex
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

from dynabarn.errors import NotInstalledHere
from dynabarn.interfaces import CheckedConfig
from dynabarn.ros import READY_WHEN

ROS_PYTHON_ENV = "DYNABARN_ROS_PYTHON"
"""Names the Python that has rospy (default: Debian's /usr/bin/python3)."""


def ros_python(ros: int = 1) -> str:
    """The interpreter that runs the bridge node: for ROS 1, one that imports rospy (Debian's
    ROS 1 packages: `make ros-deps`); for ROS 2, Debian's, which `make ros2-core` builds rclpy
    for (the prefix is checked when its domain is claimed: `domain.Ros2Domain`)."""
    if ros == 2:
        return "/usr/bin/python3"
    return _checked_ros_python(os.environ.get(ROS_PYTHON_ENV) or "/usr/bin/python3")


@functools.cache
def _checked_ros_python(exe: str) -> str:
    """`exe`, once it has shown it imports rospy (checked once per interpreter and process:
    the check starts a Python, and every episode's bridge asks)."""
    try:
        ok = subprocess.run([exe, "-c", "import rospy"], capture_output=True, timeout=60).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        ok = False
    if not ok:
        raise NotInstalledHere(
            f"{exe} cannot import rospy: install Debian's ROS 1 packages (`make ros-deps`, as root) "
            f"or set {ROS_PYTHON_ENV} to a Python that has rospy",
            "sudo make ros-deps",
        )
    return exe


BRIDGE_TOPICS = (
    "/clock",
    "/front/scan",
    "/odometry/filtered",
    "/tf",
    "/tf_static",
    "/move_base_simple/goal",
    "/collision",
    "/dynabarn/ground_truth",
    "/jackal_velocity_controller/odom",
    "/cmd_vel",
    "/jackal_velocity_controller/cmd_vel",
)
"""The topics the bridge node (`node.py`, which imports nothing of this package) publishes
and subscribes to: what `--remap` may rename (a test holds this list to the node's)."""


def remap_problem(remap: object) -> str | None:
    """Why `remap` is not a `/from:=/to` renaming of one of the bridge's topics, or None."""
    if not isinstance(remap, str):
        return "not a string"
    source, sep, target = remap.partition(":=")
    if not sep or not source.startswith("/") or not target.startswith("/") or any(c.isspace() for c in remap):
        return "use /from:=/to, e.g. /front/scan:=/scan"
    if source not in BRIDGE_TOPICS:
        return f"the bridge has no topic {source}; it has {', '.join(BRIDGE_TOPICS)}"
    return None


@dataclass
class BridgeConfig(CheckedConfig):
    """How the bridge meets the stack."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "rate": (0.01, 100.0),
        "timeout": (0.1, 600.0),
        "grace": (0.001, 600.0),
        "ready_timeout": (0.1, 600.0),
        "stack_rate": (0.0, 1000.0),
    }
    """The ranges `dynabarn-ros` gives its options, for a configuration from anywhere."""

    lockstep: bool = True
    """The simulation waits for the stack every control period (see `grace`)."""
    rate: float = 1.0
    """Real-time factor when not in lockstep (1 = real time, as Gazebo runs)."""
    timeout: float | None = None
    """Wall seconds without any /cmd_vel, in lockstep, before the episode ends as an error
    (default: 10, or the `stack`'s own: `silence_limit`)."""
    grace: float = 0.5
    """Wall seconds a lockstep period waits for a /cmd_vel after its scan before the last
    command holds for it (a stack that plans, or runs a slower loop, skips periods)."""
    ready: str = "command"
    """When the boot ends: `command` (a /cmd_vel after the goal) or `subscribed` (the scan)."""
    ready_timeout: float | None = None
    """Wall seconds the boot may take before the episode ends as an error naming what is
    missing (default: 30, or the `stack`'s own: `boot_limit`)."""
    stack_rate: float = 0.0
    """[Hz] of the stack's control loop when it runs from a timer (move_base:
    controller_frequency); 0: the stack answers each scan. Our stacks know theirs."""
    clock_step: float = 0.005
    """[s] of simulated time between /clock messages (the physics step: timers fire on time)."""
    remaps: list[str] = field(default_factory=list)
    """`from:=to` remappings of the bridge's topic names."""
    launch: str | list[str] | None = None
    """Command that starts the stack (run once the master is up; stopped at the end): a shell
    line, or its words."""
    stack: str | None = None
    """A stack of ours instead of `launch` (`dynabarn.ros.stacks`: move_base from `make ros-nav`,
    Nav2 from `make nav2`)."""
    nav_workspace: str | None = None
    """Where `make ros-nav` built move_base, or `make nav2` Nav2, for `stack` (default:
    `$DYNABARN_NAV_WS` or ~/.cache/dynabarn/ros_nav; `$DYNABARN_NAV2_WS` or ~/.cache/dynabarn/nav2)."""
    ros: int = 1
    """Which ROS the stack runs on: 1 (Debian's ROS 1, a rosmaster of the bridge's own) or 2
    (the ROS 2 Jazzy `make ros2-core` built, a DDS domain of the bridge's own: `node2.py`)."""
    ros2_workspace: str | None = None
    """Where `make ros2-core` built ROS 2 (default: `$DYNABARN_ROS2_WS` or ~/.cache/dynabarn/ros2)."""
    stack_log: str | None = None
    """File for the stack's output (default: this process's stderr; never its stdout)."""
    ros2_bag: str | None = None
    """A folder for `ros2 bag record` (rosbag2, MCAP) in the bridge's domain (ROS 2 only):
    every topic the bridge and the stack publish, from the boot to the end; the episode
    starts once the recorder has subscribed to each of the bridge's topics."""
    announce: bool = False
    """Say on stderr, as the episode starts, where the master is and where the stack's
    output goes (`dynabarn-ros`: a user who wants to `rostopic echo` the run needs it)."""

    def __post_init__(self) -> None:
        if self.ready not in READY_WHEN:
            raise ValueError(f"ready {self.ready!r}: use one of {', '.join(READY_WHEN)}")
        if self.ros not in (1, 2):
            raise ValueError(f"ros {self.ros!r}: use 1 or 2")
        if self.ros2_bag is not None and self.ros != 2:
            raise ValueError("ros2_bag: `ros2 bag record` runs on ROS 2 (ros 2) only")
        if not 0.0001 <= self.clock_step <= 0.1:
            raise ValueError(f"clock_step {self.clock_step!r}: use a step in [0.0001, 0.1] s")

    @property
    def silence_limit(self) -> float:
        """`timeout`, or the stack's own where it is not given (Nav2's recoveries stay silent
        for seconds: its Wait), or 10 s."""
        if self.timeout is not None:
            return self.timeout
        if self.stack:
            from dynabarn.ros.stacks import STACKS

            return STACKS[self.stack].timeout
        return 10.0

    @property
    def boot_limit(self) -> float:
        """`ready_timeout`, or the stack's own where it is not given (Nav2 brings up its
        servers one by one), or 30 s."""
        if self.ready_timeout is not None:
            return self.ready_timeout
        if self.stack:
            from dynabarn.ros.stacks import STACKS

            return STACKS[self.stack].boot
        return 30.0

    def check(self, what: str) -> None:
        """Across fields (`interfaces.planner.check_relations`): one way to start the stack,
        a launch line that splits into words, a stack of ours that is built, remappings of
        the bridge's own topics."""
        for remap in self.remaps:
            problem = remap_problem(remap)
            if problem:
                raise TypeError(f"{what} remap {remap!r}: {problem}")
        if self.launch and self.stack:
            raise TypeError(f"{what}: give a launch command or a stack of ours, not both (--ros-launch, --ros-stack)")
        words = self.launch
        if isinstance(self.launch, str):
            try:
                words = shlex.split(self.launch)
            except ValueError as exc:  # an unbalanced quote
                raise TypeError(f"{what} launch {self.launch!r}: {exc}") from None
        if self.launch is not None and not (isinstance(words, list) and all(isinstance(w, str) for w in words)):
            raise TypeError(f"{what} launch {self.launch!r}: a command line, or a list of its words")
        if self.launch is not None and not words:
            raise TypeError(
                f"{what} launch {self.launch!r}: an empty command; leave it out to start the stack yourself"
            )
        if self.stack:
            from dynabarn.ros.stacks import STACKS, stack_command

            STACKS.get_item(self.stack)  # one line for an unknown name, with the nearest
            if STACKS[self.stack].ros != self.ros:
                raise TypeError(f"{what} stack {self.stack!r} runs on ROS {STACKS[self.stack].ros}, not ROS {self.ros}")
            stack_command(self.stack, Path(self.nav_workspace) if self.nav_workspace else None)
