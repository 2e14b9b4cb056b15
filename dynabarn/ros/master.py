"""A ROS master for the bridge: one given by URI, or a `rosmaster` of our own on a free
loopback port, and how the processes the bridge starts are stopped."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import time
import uuid
import xmlrpc.client
from dataclasses import dataclass

from dynabarn.errors import DynabarnError, NotInstalledHere
from dynabarn.processes import die_with_parent


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _master_up(uri: str) -> bool:
    try:
        code, _, _ = xmlrpc.client.ServerProxy(uri).getSystemState("/dynabarn")
        return code == 1
    except (OSError, xmlrpc.client.Error):
        return False


@dataclass
class RosMaster:
    """A ROS master: one given by URI, or a `rosmaster` of our own on a free port (stopped
    with `close`), so parallel bridges never share one."""

    uri: str
    process: subprocess.Popen | None = None

    @classmethod
    def start(cls, uri: str | None = None, *, timeout: float = 30.0) -> RosMaster:
        if uri:
            if not _master_up(uri):
                raise DynabarnError(f"no ROS master answers at {uri}")
            return cls(uri)
        # The master alone, not `roscore`: roscore adds rosout, a roscpp node whose servers
        # listen on every interface whatever ROS_HOSTNAME says; rosmaster (rospy) listens on
        # loopback under ROS_HOSTNAME=127.0.0.1, and nothing of ours needs rosout.
        rosmaster = shutil.which("rosmaster")
        if rosmaster is None:
            raise NotInstalledHere(
                "rosmaster is not installed: install Debian's ROS 1 packages (`sudo make ros-deps`)",
                "sudo make ros-deps",
            )
        port = _free_port()
        uri = f"http://127.0.0.1:{port}/"
        env = {**os.environ, "ROS_MASTER_URI": uri, "ROS_HOSTNAME": "127.0.0.1"}
        env.pop("ROS_IP", None)  # it would take precedence over ROS_HOSTNAME
        process = subprocess.Popen(
            [rosmaster, "--core", "-p", str(port)],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            preexec_fn=die_with_parent(),
        )
        master = cls(uri, process)
        deadline = time.monotonic() + timeout
        while not _master_up(uri):
            if process.poll() is not None or time.monotonic() > deadline:
                master.close()
                raise DynabarnError(f"rosmaster did not start on port {port}")
            time.sleep(0.1)
        # Before any node starts: every node (the stack's, rostopic) then runs on /clock;
        # /run_id as roscore sets it (roslaunch and the nodes' log folders read it).
        master_api = xmlrpc.client.ServerProxy(uri)
        master_api.setParam("/dynabarn", "/use_sim_time", True)
        master_api.setParam("/dynabarn", "/run_id", str(uuid.uuid4()))
        return master

    def env(self) -> dict[str, str]:
        return {**os.environ, "ROS_MASTER_URI": self.uri, "ROS_HOSTNAME": "127.0.0.1"}

    def close(self) -> None:
        if self.process is not None:
            stop_process(self.process)
            self.process = None


def stop_process(process: subprocess.Popen, timeout: float = 10.0) -> None:
    """SIGINT (as roslaunch and ros2 launch expect), then SIGTERM, then SIGKILL, to the
    process group; once its leader is gone, SIGKILL to whatever of the group is left (a
    node that hung in its shutdown after `ros2 launch` gave up on it)."""
    if process.poll() is None:
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(process.pid, sig)
            except (ProcessLookupError, PermissionError):
                break
            try:
                process.wait(timeout=timeout if sig != signal.SIGKILL else None)
                break
            except subprocess.TimeoutExpired:
                continue
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(process.pid, signal.SIGKILL)  # nothing of the group outlives the episode
