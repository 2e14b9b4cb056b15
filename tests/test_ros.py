"""`dynabarn-ros` with real ROS 1: Debian's roscore and rospy, the bridge node, and a rospy
navigation stack written for the test (`tests/ros_stack.py`, with an actionlib move_base
server). Skipped where Debian's ROS packages are missing (`make ros-deps` installs them)."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

STACK = Path(__file__).resolve().parent / "ros_stack.py"


def _ros_available() -> bool:
    if shutil.which("roscore") is None or not Path("/usr/bin/python3").exists():
        return False
    return subprocess.run(["/usr/bin/python3", "-c", "import rospy, actionlib"], capture_output=True).returncode == 0


pytestmark = pytest.mark.skipif(not _ros_available(), reason="Debian's ROS 1 packages: make ros-deps (root)")


def _ros(*argv: str, timeout: float = 180) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "dynabarn", "ros", *argv], capture_output=True, text=True, timeout=timeout
    )


def _stack(*flags: str) -> str:
    return " ".join(["/usr/bin/python3", str(STACK), *flags])


def test_a_rospy_stack_reaches_the_goal_the_same_way_twice_in_lockstep(tmp_path):
    from dynabarn.recording import message_digest, read_recording

    results = []
    for k in range(2):
        log = tmp_path / f"run{k}.mcap"
        proc = _ros("--world", "137", "--launch", _stack(), "--log", str(log), "--json")
        assert proc.returncode == 0, proc.stderr
        results.append((json.loads(proc.stdout), message_digest(log)))
    (first, digest1), (second, digest2) = results
    assert first["outcome"] == "success" and first["planner"] == "ros"
    for key in ("time", "path_length", "min_clearance", "n_ticks", "world_sha256"):
        assert first[key] == second[key], key
    assert digest1 == digest2  # the recordings too, message for message
    assert first["planner_config"]["lockstep"] is True and first["bridge_ms_per_tick"] < 20
    rec = read_recording(tmp_path / "run0.mcap")
    assert rec.metadata["planner"] == "ros" and len(rec.topic("/scan")) == first["n_ticks"]


def test_the_goal_through_the_move_base_action(tmp_path):
    proc = _ros("--world", "0", "--launch", _stack("--goal-from", "action"), "--no-log")
    assert proc.returncode == 0, proc.stderr
    assert "world_000 | ros | barn | seed 0: SUCCESS" in proc.stdout


def test_a_stack_that_dies_ends_the_episode_as_an_error():
    proc = _ros("--world", "0", "--launch", _stack("--die-after", "20"), "--no-log", "--timeout", "2")
    assert proc.returncode == 1
    assert "ERROR" in proc.stdout and "the ROS stack exited with status 3" in proc.stderr


def test_a_stack_that_never_answers_ends_the_episode_as_an_error():
    proc = _ros("--world", "0", "--launch", _stack("--mute"), "--no-log", "--timeout", "2", "--json")
    assert proc.returncode == 1
    result = json.loads(proc.stdout)
    assert result["outcome"] == "error" and "did not answer on /cmd_vel within 2 s" in result["reason"]
    assert result["n_ticks"] == 0  # the first control period was never answered


def test_no_stack_at_all_is_one_clear_error():
    proc = _ros("--world", "0", "--no-log", "--ready-timeout", "1")
    assert proc.returncode == 1 and "no ROS stack subscribed to the scan within 1 s" in proc.stderr


def test_remapped_topics():
    remaps = ("/front/scan:=/scan", "/cmd_vel:=/jackal/cmd_vel")
    stack = _stack(*remaps)
    proc = _ros("--world", "0", "--launch", stack, "--no-log", *[a for r in remaps for a in ("--remap", r)])
    assert proc.returncode == 0, proc.stderr
    assert "SUCCESS" in proc.stdout
    # Remapped on one side only: the stack hears nothing.
    proc = _ros(
        "--world", "0", "--launch", _stack(), "--no-log", "--remap", "/front/scan:=/scan", "--ready-timeout", "2"
    )
    assert proc.returncode == 1 and "no ROS stack subscribed" in proc.stderr


def test_rostopic_hz_sees_the_scan_at_10_hz_of_sim_time():
    from dynabarn.ros.bridge import RosMaster

    master = RosMaster.start()
    env = master.env()
    launch = ("--launch", _stack())
    try:
        bridge = subprocess.Popen(
            [sys.executable, "-m", "dynabarn", "ros", "--world", "137", "--master", master.uri, "--no-log", *launch],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        time.sleep(2.0)
        hz = subprocess.run(
            ["rostopic", "hz", "-w", "30", "/front/scan"], env=env, capture_output=True, text=True, timeout=30
        )
        bridge.communicate(timeout=120)
    except subprocess.TimeoutExpired as exc:  # rostopic hz runs until stopped: read what it printed
        hz = exc
    finally:
        master.close()
    out = hz.stdout if isinstance(hz.stdout, str) else (hz.stdout or b"").decode()
    rates = [float(r) for r in re.findall(r"average rate: ([0-9.]+)", out)]
    assert rates, out
    assert all(abs(r - 10.0) < 0.2 for r in rates), rates


def test_missing_ros_is_one_line(tmp_path):
    env = {**os.environ, "DYNABARN_ROS_PYTHON": str(tmp_path / "no_python")}
    proc = subprocess.run(
        [sys.executable, "-m", "dynabarn", "ros", "--world", "0", "--no-log"], capture_output=True, text=True, env=env
    )
    assert proc.returncode == 2 and "cannot import rospy" in proc.stderr and proc.stderr.count("\n") == 1
