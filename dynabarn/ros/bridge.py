"""The simulation side of `dynabarn-ros`: a ROS master, the rospy node (`node.py`, run by
Debian's Python, where rospy lives) and a `Planner` whose commands come from a ROS stack.

Why two processes: Debian's ROS 1 packages are built for `/usr/bin/python3`, and the
project's Python (with MuJoCo) may be another. The node imports nothing of dynabarn; the
two speak length-prefixed binary frames over a pipe (see `node.py`). Because the commands
come through an ordinary `Planner`, `run_episode` judges, times and records a ROS stack's
episode exactly like any other planner's.

The odometry frame is the BARN Challenge's: `odom` starts at the robot's spawn, x forward;
the goal is given in it. The true pose (world frame) is on /dynabarn/ground_truth.
"""

from __future__ import annotations

import math
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import ClassVar

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import EpisodeInfo, Observation, Planner
from dynabarn.processes import die_with_parent
from dynabarn.robot import JACKAL
from dynabarn.ros.bridge_config import BridgeConfig, ros_python
from dynabarn.ros.domain import Ros2Domain
from dynabarn.ros.master import RosMaster, stop_process
from dynabarn.ros.node import COMMAND, ENDED, GOAL, HEADER, OBSERVATION, READY, write_frame

NODE = Path(__file__).resolve().parent / "node.py"
"""The rospy side; its frames (HEADER, OBSERVATION, ...) are the wire format's one definition."""
NODE2 = Path(__file__).resolve().parent / "node2.py"
"""The rclpy side: `node.py`'s node over ROS 2."""


class RosPlanner(Planner):
    """A ROS navigation stack, reached through the bridge node, as a `Planner`."""

    name = "ros"
    external_options: ClassVar[dict[str, str]] = {
        "launch": "a program it runs (the stack)",
        "nav_workspace": "a workspace whose setup script it runs",
        "stack_log": "a file it writes",
        "ros2_bag": "a folder it writes",
        "master": "a ROS master it connects to",
    }

    def __init__(self, master: RosMaster | Ros2Domain, config: BridgeConfig | None = None) -> None:
        self.master = master
        self.cfg = config or BridgeConfig()
        self.node: subprocess.Popen | None = None
        self.stack: subprocess.Popen | None = None
        self.recorder: subprocess.Popen | None = None
        """`ros2 bag record` in the domain (`BridgeConfig.ros2_bag`)."""
        self.tick_ms: list[float] = []
        """The bridge's own time per control period [ms] (packing, pipe, publishing)."""
        self.round_trip_ms: list[float] = []
        """Observation out to command back, per control period (the boot and pacing not counted) [ms]."""
        self.held = 0
        """Lockstep periods the stack let pass without a /cmd_vel (the last command held)."""
        self.ended = 0
        """Periods after the stack's navigation action ended (Nav2 gave up): the robot stood."""
        self.waited_ms = 0.0
        """Wall time of the last `act` spent on the boot or the pacing (the loop leaves it out
        of the planner's time)."""
        self.steady_since: float | None = None
        self.steady_sim_time = 0.0
        """perf_counter and simulated time of the first control period after the boot."""

    def config(self) -> dict:
        c = self.cfg
        return {
            "lockstep": c.lockstep,
            "rate": c.rate,
            "grace": c.grace,
            "ready": c.ready,
            "clock_step": c.clock_step,
            "stack_rate": c.stack_rate,
            "launch": c.launch,
            "stack": c.stack,
            "remaps": list(c.remaps),
            **({"ros": c.ros} if c.ros != 1 else {}),  # ROS 1's runs recorded as before
        }

    def reset(self, info: EpisodeInfo) -> None:
        angles = info.laser_angles
        env = self.master.env()
        c = self.cfg
        cmd = [
            ros_python(c.ros),
            str(NODE2 if c.ros == 2 else NODE),
            *c.remaps,
            "--timeout",
            str(c.silence_limit),
            "--grace",
            str(min(c.grace, c.silence_limit)),
        ]
        cmd += ["--ready", c.ready, "--ready-timeout", str(c.boot_limit), "--clock-step", repr(c.clock_step)]
        cmd += ["--period", repr(info.control_period), "--rate", repr(c.rate)]
        cmd += ["--angle-min", repr(float(angles[0])), "--angle-max", repr(float(angles[-1]))]
        cmd += ["--range-min", repr(float(info.laser_range[0])), "--range-max", repr(float(info.laser_range[1]))]
        cmd += ["--laser-x", repr(float(info.laser_offset[0])), "--laser-z", repr(JACKAL.laser_z)]
        if not c.lockstep:
            cmd.append("--paced")
        launch, rate = c.launch, c.stack_rate
        if c.stack:
            from dynabarn.ros.stacks import STACKS, stack_command

            launch = stack_command(c.stack, Path(c.nav_workspace) if c.nav_workspace else None)
            rate = rate or STACKS[c.stack].control_rate
        cmd += ["--stack-rate", repr(float(rate))]
        if c.announce:  # the master is up; the stack is about to start
            mode = "lockstep" if c.lockstep else f"paced at {c.rate:g}x"
            where = f"; stack output: {c.stack_log}" if c.stack_log and launch else ""
            where_ros = f"ROS master {self.master.uri}" if c.ros == 1 else f"ROS 2 in {self.master.uri}"
            print(f"{where_ros}; {mode}{where}", file=sys.stderr, flush=True)
        if c.ros2_bag:
            self.recorder = start_recorder(Path(c.ros2_bag), env)
            cmd += ["--recorder", RECORDER]
        self.node = spawn(cmd, env, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        if launch:
            # The stack's output never reaches our stdout (a --json document is printed there).
            log = open(c.stack_log, "ab") if c.stack_log else sys.stderr  # noqa: SIM115 (the stack writes while it runs)
            try:
                words = shlex.split(launch) if isinstance(launch, str) else list(launch)
                self.stack = spawn(words, env, stdout=log, stderr=subprocess.STDOUT)
            finally:
                if c.stack_log:
                    log.close()
        self._origin = None
        self._wall0 = None
        self._answered_at = None
        self.held = self.ended = 0
        self.steady_since = None
        self.t0 = 0.0

    def _to_odom(self, x: float, y: float, yaw: float) -> tuple[float, float, float]:
        x0, y0, yaw0 = self._origin
        c, s = math.cos(yaw0), math.sin(yaw0)
        dx, dy = x - x0, y - y0
        return c * dx + s * dy, -s * dx + c * dy, math.atan2(math.sin(yaw - yaw0), math.cos(yaw - yaw0))

    def _observation(self, obs: Observation) -> bytes:
        x, y, yaw = self._to_odom(*(float(v) for v in obs.pose))
        ranges = np.asarray(obs.scan, dtype="<f4")
        wx, wy, wyaw = (float(v) for v in obs.pose)
        v, w = float(obs.velocity[0]), float(obs.velocity[1])
        return OBSERVATION.pack(obs.time, x, y, yaw, v, w, wx, wy, wyaw, len(ranges)) + ranges.tobytes()

    def act(self, obs: Observation) -> tuple[float, float]:
        start = time.perf_counter()
        if self._origin is None:  # the first tick: odom starts here; boot until the stack is ready
            self._boot(obs)
        if not self.cfg.lockstep:  # paced: as Gazebo runs, rate x real time
            wait = self._wall0 + obs.time / self.cfg.rate - time.monotonic()
            if wait > 0:
                time.sleep(wait)
        t0 = time.perf_counter()
        self.waited_ms = (t0 - start) * 1e3  # the boot and the pacing: not the stack's planning time
        self._send(b"O", self._observation(obs))
        sent = time.perf_counter()
        body = self._receive(b"C", self.cfg.grace + 30)
        v, w, answered = COMMAND.unpack(body)
        done = time.perf_counter()
        self.tick_ms.append((sent - t0) * 1e3)
        self.round_trip_ms.append((done - t0) * 1e3)
        if self.steady_since is None:
            self.steady_since, self.steady_sim_time = t0, obs.time
        now = time.monotonic()
        if answered == ENDED:  # the stack's navigation ended: the robot stands, nothing is awaited
            self.ended += 1
            self._answered_at = now
        elif answered:
            self._answered_at = now
        else:
            self.held += 1
            if now - self._answered_at > self.cfg.silence_limit:
                self._check_stack()
                raise RuntimeError(f"the ROS stack did not answer on /cmd_vel within {self.cfg.silence_limit:g} s")
        return v, w

    def _boot(self, obs: Observation) -> None:
        self._origin = tuple(float(v) for v in obs.pose)
        gx, gy, _ = self._to_odom(float(obs.goal_in_world[0]), float(obs.goal_in_world[1]), 0.0)
        self._send(b"B", self._observation(obs) + GOAL.pack(gx, gy, 0.0))
        body = self._receive(b"R", self.cfg.boot_limit + 30)
        self.t0, ready = READY.unpack_from(body)
        if not ready:
            self._check_stack()
            missing = body[READY.size :].decode(errors="replace")
            raise RuntimeError(
                f"the ROS stack was not ready ({self.cfg.ready}) within {self.cfg.boot_limit:g} s: {missing}"
            )
        self._wall0 = self._answered_at = time.monotonic()

    def _check_stack(self) -> None:
        if self.stack is not None and self.stack.poll() is not None:
            raise RuntimeError(f"the ROS stack exited with status {self.stack.returncode}")

    def _send(self, kind: bytes, body: bytes) -> None:
        try:
            write_frame(self.node.stdin, kind, body)
        except (BrokenPipeError, OSError):
            raise RuntimeError(f"the bridge node stopped (status {self.node.poll()})") from None

    def _receive(self, kind: bytes, timeout: float) -> bytes:
        import select

        out = self.node.stdout
        ready, _, _ = select.select([out], [], [], timeout)
        head = out.read(HEADER.size) if ready else b""
        if len(head) < HEADER.size:
            self._check_stack()
            raise RuntimeError(f"the bridge node stopped answering (status {self.node.poll()})")
        got, size = HEADER.unpack(head)
        body = out.read(size)
        if got != kind or len(body) != size:
            raise RuntimeError(f"the bridge node sent {got!r} instead of {kind!r}")
        return body

    def finish(self, outcome: str) -> None:
        """Tell the stack how the episode ended (/collision), then stop the stack, the node
        and the master this planner started (one given by its URI is left running). Safe to
        call again: nothing is stopped twice."""
        if self.node is not None and self.node.poll() is None:
            try:
                self._send(b"E", outcome.encode())
                self.node.stdin.close()
            except RuntimeError:
                pass
        # The recorder after the stack (its last messages in the bag), SIGINT first: rosbag2
        # then writes the MCAP's summary and metadata.yaml.
        for process in (self.stack, self.recorder, self.node):
            if process is not None:
                stop_process(process, timeout=5.0 if process is not self.recorder else 30.0)
        self.stack = self.recorder = self.node = None
        self.master.close()

    def report(self) -> dict:
        """The bridge's cost and the stack's punctuality: the median bridge time per control
        period [ms] (None when none ran) and the lockstep periods without a /cmd_vel."""
        overhead = bridge_overhead(self)
        return {
            "bridge_ms_per_tick": None if overhead is None else round(overhead, 3),
            "held_periods": self.held,
            "periods_after_navigation_ended": self.ended,
        }


def spawn(
    cmd: list[str],
    env: dict[str, str],
    *,
    stdin=subprocess.DEVNULL,
    stdout=subprocess.DEVNULL,
    stderr=subprocess.DEVNULL,
) -> subprocess.Popen:
    """A process of the bridge's (the node, the stack, the recorder): in a process group of
    its own (stopped whole, `stop_process`) that dies with this process."""
    return subprocess.Popen(
        cmd, env=env, stdin=stdin, stdout=stdout, stderr=stderr, start_new_session=True, preexec_fn=die_with_parent()
    )


RECORDER = "dynabarn_recorder"
"""The node name `ros2 bag record` runs under: the bridge node waits for its subscriptions."""
RECORDER_QOS = Path(__file__).resolve().parent / "launch" / "rosbag2" / "qos_overrides.yaml"
"""Its QoS where rosbag2's default would lose messages (/clock's bursts)."""


def check_bag_folder(folder: Path) -> None:
    """A folder `ros2 bag record` can write: new, in a folder that exists (rosbag2 refuses
    one that exists); one line otherwise."""
    if folder.exists():
        raise DynabarnError(f"{folder}: exists (rosbag2 writes a new folder; move it or name another)")
    if not folder.parent.is_dir():
        raise DynabarnError(f"{folder.parent}: no such folder for the ROS 2 bag")


def start_recorder(folder: Path, env: dict[str, str]) -> subprocess.Popen:
    """`ros2 bag record` of every topic (services left out) into `folder` (MCAP storage), on
    the bridge's clock, in its process group; the bridge node's boot waits until it has
    subscribed to each of the bridge's topics."""
    check_bag_folder(folder)
    cmd = ["ros2", "bag", "record", "--all-topics", "--use-sim-time", "--storage", "mcap"]
    cmd += ["--node-name", RECORDER, "--qos-profile-overrides-path", str(RECORDER_QOS), "--output", str(folder)]
    return spawn(cmd, env)


def ros_planner(*, launch: str | None = None, master: str | None = None, **config) -> RosPlanner:
    """The `ros` planner of the registry (entry point): for `dynabarn-run --planner ros` and
    `dynabarn-bench --planner ros --ros-launch CMD`. Each planner starts a master of its own
    on a free port (parallel workers never share one) unless `master` names a running one,
    and stops it in `finish`; the stack is started per episode by `launch` and stopped when
    the episode ends."""
    from dynabarn.interfaces import config_from_kwargs

    cfg = config_from_kwargs(BridgeConfig, {"launch": launch, **config}, "ros")
    if cfg.ros == 2:  # no master: a DDS domain of its own, in the prefix `make ros2-core` built
        if master is not None:
            raise TypeError("ros master: ROS 2 has no master (each bridge takes a DDS domain of its own)")
        from dynabarn.ros import nav2_build
        from dynabarn.ros.stacks import nav2_setup

        # The bridge runs in Nav2's overlay where `make nav2` built one (its nav2_msgs: the
        # goal through `navigate_to_pose`, also for a Nav2 started by --launch); a Nav2
        # stack of ours needs it.
        overlay = None
        if cfg.stack:
            overlay = nav2_setup(Path(cfg.nav_workspace) if cfg.nav_workspace else None)
        elif nav2_build.built(nav2_build.default_workspace()) is not None:
            overlay = nav2_setup()
        core = Path(cfg.ros2_workspace) if cfg.ros2_workspace else None
        return RosPlanner(Ros2Domain.start(core, overlay), cfg)
    if master is None:
        ros_python()  # one clear line when ROS is missing, before a master is started
    return RosPlanner(RosMaster.start(master), cfg)


ros_planner.external_options = RosPlanner.external_options  # type: ignore[attr-defined]


def bridge_overhead(planner: RosPlanner) -> float | None:
    """Median bridge time per control period [ms] (excluding the stack's answer, the boot
    and the pacing); None when no period ran."""
    return float(np.median(planner.tick_ms)) if planner.tick_ms else None


__all__ = ["NODE", "BridgeConfig", "RosMaster", "RosPlanner", "bridge_overhead", "ros_planner", "ros_python"]
