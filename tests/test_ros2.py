"""ROS 2 in the loop (`dynabarn-ros --ros 2`): the core `make ros2-core` builds, the bridge
node over rclpy against real rclpy nodes, and a rclpy stack of ours driving world 137.
Where no ROS 2 prefix is built (CI cannot fetch its sources) each test skips with the
command that builds it; the build's own checks (its sources, its record) run everywhere."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dynabarn.errors import DynabarnError
from dynabarn.ros import ros2_build

HERE = Path(__file__).resolve().parent
BIN = Path(sys.executable).parent


def _prefix() -> Path:
    workspace = ros2_build.default_workspace()
    if ros2_build.built(workspace) is None:
        pytest.skip(f"ROS 2 is not built in {workspace}: make ros2-core ROS2_SRC=<folder of the fetched repositories>")
    return workspace


def test_the_repositories_are_one_release_sync_and_a_wrong_folder_is_one_line(tmp_path):
    """The vcstool file lists every repository at its version; sources of another version,
    or none, are refused naming them, before anything is built."""
    text = ros2_build.repos_file()
    every = len(ros2_build.REPOSITORIES) + len(ros2_build.DOWNLOADS)
    assert text.startswith("repositories:\n") and text.count("type: git") == every
    assert "    url: https://github.com/ros2/rclpy.git\n    version: 7.1.3" in text
    assert (
        "  mcap:\n    type: git\n    url: https://github.com/foxglove/mcap.git\n    version: releases/cpp/v1.3.0"
        in text
    )
    with pytest.raises(DynabarnError, match="no such folder"):
        ros2_build.find_sources(tmp_path / "nowhere")
    (tmp_path / "rclpy" / "rclpy").mkdir(parents=True)
    (tmp_path / "rclpy" / "rclpy" / "package.xml").write_text(
        "<package><name>rclpy</name><version>9.9.9</version></package>"
    )
    with pytest.raises(
        DynabarnError, match=r"not the sources of release-jazzy-20241223: .*rclpy \(9\.9\.9, not 7\.1\.3\)"
    ):
        ros2_build.find_sources(tmp_path)
    # A download (not a ROS package) is checked by its version line: MCAP of another release.
    header = tmp_path / "mcap" / "cpp" / "mcap" / "include" / "mcap" / "types.hpp"
    header.parent.mkdir(parents=True)
    header.write_text('#define MCAP_LIBRARY_VERSION "2.1.3"\n')
    with pytest.raises(DynabarnError, match=r"mcap \(not releases/cpp/v1\.3\.0: .*types\.hpp lacks"):
        ros2_build.find_sources(tmp_path)
    out = subprocess.run(
        [
            str(BIN / "python"),
            "-m",
            "dynabarn.ros.ros2_build",
            "--source",
            str(tmp_path),
            "--workspace",
            str(tmp_path / "ws"),
        ],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1 and "missing" in out.stderr


def test_the_built_prefix_says_what_it_holds():
    """The record of `make ros2-core`: the sync, every package a stack and the bridge need,
    the size; rclpy imports in the prefix's environment with Cyclone DDS."""
    workspace = _prefix()
    record = ros2_build.built(workspace)
    assert record["sync"] == ros2_build.SYNC and set(ros2_build.CORE_PACKAGES) <= set(record["packages"])
    assert record["install_bytes"] > 10e6
    from dynabarn.ros.domain import Ros2Domain

    domain = Ros2Domain.start(workspace)
    try:
        code = "from rclpy.utilities import get_rmw_implementation_identifier as rmw; print(rmw())"
        env = domain.env()
        done = subprocess.run(["/usr/bin/python3", "-c", code], env=env, capture_output=True, text=True, timeout=60)
        assert done.returncode == 0 and done.stdout.strip() == "rmw_cyclonedds_cpp", done.stderr
    finally:
        domain.close()


def test_two_bridges_never_share_a_domain():
    workspace = _prefix()
    from dynabarn.ros.domain import Ros2Domain

    a, b = Ros2Domain.start(workspace), Ros2Domain.start(workspace)
    try:
        assert a.domain != b.domain and a.env()["ROS_DOMAIN_ID"] == str(a.domain)
        assert a.env()["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    finally:
        a.close()
        b.close()


def test_a_rclpy_stack_drives_world_137_in_lockstep(tmp_path):
    """Our rclpy stack (tests/ros2_stack.py) on the bridge: the goal from /goal_pose, scans
    with the sensor-data QoS, /clock with use_sim_time; it reaches the goal, every control
    period answered (none held), and the episode is recorded like any other."""
    workspace = _prefix()
    log = tmp_path / "ros2.mcap"
    out = subprocess.run(
        [str(BIN / "dynabarn-ros"), "--ros", "2", "--ros2-workspace", str(workspace), "--world", "137",
         "--launch", f"/usr/bin/python3 {HERE / 'ros2_stack.py'}", "--log", str(log), "--json", "--bag",
         "--grace", "5"],  # a loaded machine's slow answer waits, never held
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "PYTHONSAFEPATH": "1"},  # as after a sweep or a vector env in this process
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout)
    assert result["outcome"] == "success" and result["held_periods"] == 0, result
    assert result["planner_config"]["ros"] == 2
    assert log.is_file()
    # --bag: the recording as a ROS 2 bag beside it, read back by rosbags' reader.
    from rosbags.rosbag2 import Reader

    bag = Path(result["bag"])
    assert bag == tmp_path / "ros2_rosbag2"
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts["/front/scan"] == result["n_ticks"] and counts["/tf_static"] == 1


def test_a_stack_that_never_answers_ends_as_an_error_naming_what_is_missing(tmp_path):
    workspace = _prefix()
    out = subprocess.run(
        [str(BIN / "dynabarn-ros"), "--ros", "2", "--ros2-workspace", str(workspace), "--world", "137",
         "--launch", f"/usr/bin/python3 {HERE / 'ros2_stack.py'} --mute", "--no-log", "--json",
         "--ready-timeout", "5"],
        capture_output=True,
        text=True,
        timeout=300,
    )  # fmt: skip
    result = json.loads(out.stdout)
    assert result["outcome"] == "error" and "no /cmd_vel came" in result["reason"], result


def test_the_same_stack_on_ros_1_and_ros_2_drives_the_same_episode():
    """The controller of tests/ros_stack.py (rospy) and tests/ros2_stack.py (rclpy) answers
    each scan from that scan and its odometry: through the two bridges, in lockstep, the
    same episode to the sample (what differs between them is transport, not simulation)."""
    _prefix()
    from dynabarn.ros.bridge_config import ros_python

    try:
        ros_python(1)
    except DynabarnError as exc:
        pytest.skip(str(exc))
    results = []
    for ros, stack in ((1, "ros_stack.py"), (2, "ros2_stack.py")):
        out = subprocess.run(
            [str(BIN / "dynabarn-ros"), "--ros", str(ros), "--world", "137", "--no-log", "--json", "--grace", "5",
             "--launch", f"/usr/bin/python3 {HERE / stack}"],
            capture_output=True,
            text=True,
            timeout=600,
        )  # fmt: skip
        assert out.returncode == 0, out.stderr[-2000:]
        results.append(json.loads(out.stdout))
    ros1, ros2 = results
    for key in ("outcome", "time", "path_length", "min_clearance", "n_ticks"):
        assert ros1[key] == ros2[key], (key, ros1[key], ros2[key])


def test_ros2_topic_sees_the_bridge_with_nav2s_qos():
    """`ros2 topic` in the domain the bridge announces, while the bridge boots (a stack that
    never answers keeps it booting for as long as the checks take, however loaded the
    machine): its topics listed, /tf_static and /goal_pose received by a late subscriber
    (transient-local, as ROS 1 latches them), the scan best-effort (the sensor-data profile
    Nav2 expects)."""
    import re

    workspace = _prefix()
    from dynabarn.ros.colcon import setup_script
    from dynabarn.ros.domain import prefix_env

    proc = subprocess.Popen(
        [str(BIN / "dynabarn-ros"), "--ros", "2", "--world", "137", "--no-log", "--ready-timeout", "300",
         "--launch", f"/usr/bin/python3 {HERE / 'ros2_stack.py'} --mute"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        line = proc.stderr.readline()
        domain = re.search(r"ROS_DOMAIN_ID=(\d+)", line)
        assert domain, line
        env = {
            **prefix_env(setup_script(workspace)),
            "HOME": str(Path.home()),
            "ROS_DOMAIN_ID": domain.group(1),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp",
        }

        def ros2(*words: str) -> str:
            done = subprocess.run(["ros2", *words], env=env, capture_output=True, text=True, timeout=60)
            assert done.returncode == 0, done.stderr
            return done.stdout

        topics = ros2("topic", "list", "--no-daemon")
        assert {"/clock", "/front/scan", "/odometry/filtered", "/tf", "/tf_static", "/goal_pose", "/cmd_vel"} <= set(
            topics.split()
        ), topics
        latched = ("--qos-durability", "transient_local", "--qos-reliability", "reliable", "--no-daemon")
        assert "child_frame_id: front_laser" in ros2("topic", "echo", "--once", *latched, "/tf_static")
        assert "frame_id: odom" in ros2("topic", "echo", "--once", *latched, "/goal_pose")
        info = ros2("topic", "info", "--verbose", "/front/scan", "--no-daemon")
        assert "BEST_EFFORT" in info, info
    finally:
        proc.kill()
        proc.communicate()


def _rosbag2(workspace: Path) -> None:
    if "ros2bag" not in ros2_build.built(workspace)["packages"]:
        pytest.skip(f"rosbag2 is not in the ROS 2 core in {workspace}: make ros2-core ROS2_SRC=<folder>")


def test_ros2_bag_records_the_whole_episode_in_the_bridges_domain(tmp_path):
    """--ros2-bag: rosbag2's own `ros2 bag record` in the bridge's domain, on its clock. The
    episode waits for its subscriptions, so the bag holds every control period (a scan,
    odometry and transform each, every /clock tick of the bursts) and the stack's commands;
    read back by rosbag2 (`ros2 bag info`) and by MCAP's own reader. A folder that exists,
    or --ros2-bag on ROS 1, is one line and exit 2."""
    workspace = _prefix()
    _rosbag2(workspace)
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from dynabarn.ros.colcon import setup_script
    from dynabarn.ros.domain import prefix_env

    bag = tmp_path / "graph"
    command = [str(BIN / "dynabarn-ros"), "--world", "137", "--no-log", "--json", "--grace", "5",
               "--launch", f"/usr/bin/python3 {HERE / 'ros2_stack.py'}"]  # fmt: skip
    out = subprocess.run([*command, "--ros", "2", "--ros2-bag", str(bag)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout)
    assert result["outcome"] == "success" and result["ros2_bag"] == str(bag), result
    info = subprocess.run(
        ["ros2", "bag", "info", str(bag)],
        env={**prefix_env(setup_script(workspace)), "HOME": str(Path.home())},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert info.returncode == 0 and "Storage id:        mcap" in info.stdout, info.stderr
    counts: dict[str, int] = {}
    last_clock = 0.0
    with (bag / "graph_0.mcap").open("rb") as f:
        for _, channel, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/clock":
                last_clock = max(last_clock, msg.clock.sec + msg.clock.nanosec * 1e-9)
    for topic in ("/front/scan", "/odometry/filtered", "/tf", "/dynabarn/ground_truth", "/cmd_vel"):
        assert counts[topic] >= result["n_ticks"], (topic, counts)
    assert counts["/tf_static"] == 1 and counts["/goal_pose"] == 1 and counts["/robot_description"] == 1
    # Every 5 ms tick from the boot to the end: none lost from the bursts of a period.
    assert counts["/clock"] >= round(result["sim_time"] / 0.005), counts["/clock"]
    assert last_clock >= result["sim_time"]
    for extra, why in (
        (["--ros", "2", "--ros2-bag", str(bag)], "exists"),
        (["--ros", "1", "--ros2-bag", str(tmp_path / "x")], "--ros 2"),
    ):
        out = subprocess.run([*command, *extra], capture_output=True, text=True, timeout=120)
        assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1 and why in out.stderr, out.stderr
