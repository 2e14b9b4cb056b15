"""`dynabarn-ros` with real ROS 1: Debian's rosmaster and rospy, the bridge node, and a rospy
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

from tests.conftest import cmdline, processes_carrying, require, tagged_environment

STACK = Path(__file__).resolve().parent / "ros_stack.py"


def _ros_available() -> bool:
    if shutil.which("roscore") is None or not Path("/usr/bin/python3").exists():
        return False
    return subprocess.run(["/usr/bin/python3", "-c", "import rospy, actionlib"], capture_output=True).returncode == 0


pytestmark = [
    pytest.mark.skipif(not _ros_available(), reason="needs Debian's ROS 1 packages: sudo make ros-deps"),
    pytest.mark.slow,  # real rosmaster and rospy nodes: `make test` runs them, `make test-fast` does not
]


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


def test_a_stack_that_never_starts_is_one_strict_json_document():
    proc = _ros("--world", "0", "--launch", _stack("--mute"), "--no-log", "--ready-timeout", "2", "--json")
    assert proc.returncode == 1
    result = json.loads(proc.stdout)  # the whole stdout: one document, nothing of the stack's
    assert result["outcome"] == "error" and result["n_ticks"] == 0 and result["bridge_ms_per_tick"] is None
    assert "not ready (command) within 2 s: a node subscribed to the scan, but no /cmd_vel came" in result["reason"]


def test_a_stack_that_stops_answering_ends_the_episode_as_an_error():
    proc = _ros("--world", "0", "--launch", _stack("--mute-after", "5"), "--no-log", "--timeout", "2", "--json")
    assert proc.returncode == 1
    result = json.loads(proc.stdout)
    assert result["outcome"] == "error" and "did not answer on /cmd_vel within 2 s" in result["reason"]
    # The last command held for each silent period (0.5 s of grace each) until 2 s had passed.
    assert 3 <= result["held_periods"] <= 6 and result["n_ticks"] >= 5


def test_no_stack_at_all_is_one_clear_error():
    proc = _ros("--world", "0", "--no-log", "--ready-timeout", "1")
    assert proc.returncode == 1 and "not ready (command) within 1 s: nothing subscribed to the scan" in proc.stderr


def test_a_stack_that_starts_and_runs_like_move_base_in_lockstep_and_paced(tmp_path):
    """It waits through tf2 for odom -> base_link (on ROS time) before it subscribes, and
    publishes only from a 20 Hz timer on ROS time: the boot's running clock lets it start,
    the fine /clock lets its timer run within each lockstep period."""
    log = tmp_path / "stack.log"
    stack = _stack("--like-move-base", "--goal-from", "action")
    proc = _ros("--world", "0", "--launch", stack, "--no-log", "--json", "--stack-log", str(log))
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["outcome"] == "success" and result["held_periods"] >= 1  # its planning cycles skip periods
    assert result["stack_log"] == str(log) and log.is_file()
    # Told its loop's rate, lockstep holds the clock at each tick its timer fires on until
    # the loop answers: the loop runs at 20 Hz of simulated time, two commands a period.
    timed = _ros("--world", "0", "--launch", stack, "--no-log", "--json", "--stack-rate", "20")
    assert timed.returncode == 0, timed.stderr
    timed_result = json.loads(timed.stdout)
    assert timed_result["outcome"] == "success" and timed_result["planner_config"]["stack_rate"] == 20.0
    paced = _ros("--world", "0", "--launch", stack, "--no-log", "--json", "--rate", "4")
    assert paced.returncode == 0, paced.stderr
    assert json.loads(paced.stdout)["outcome"] == "success"


def test_ground_truth_is_in_the_world_frame():
    """/dynabarn/ground_truth: the pose in the world (the spawn at x = 11, facing -x), not odometry."""
    from dynabarn.ros.bridge import RosMaster

    master = RosMaster.start()
    script = (
        "import rospy, math\nfrom nav_msgs.msg import Odometry\nrospy.init_node('probe')\n"
        "m = rospy.wait_for_message('/dynabarn/ground_truth', Odometry, timeout=60)\n"
        "p, q = m.pose.pose.position, m.pose.pose.orientation\n"
        "print(m.header.frame_id, round(p.x, 2), round(p.y, 2), round(abs(2 * math.atan2(q.z, q.w)), 2))\n"
    )
    probe = subprocess.Popen(["/usr/bin/python3", "-c", script], env=master.env(), stdout=subprocess.PIPE, text=True)
    try:
        run = _ros("--world", "0", "--master", master.uri, "--no-log", "--launch", _stack())
        assert run.returncode == 0, run.stderr
        out, _ = probe.communicate(timeout=60)
    finally:
        probe.kill()
        master.close()
    assert out.split() == ["world", "11.0", "0.0", "3.14"], out


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
    assert proc.returncode == 1 and "nothing subscribed to the scan" in proc.stderr


def test_rostopic_hz_sees_the_scan_at_10_hz_of_sim_time():
    """rostopic measures in ROS time, which is the bridge's /clock: 10 Hz whatever the wall
    clock does (a slow stack, 30 ms per scan, keeps the episode long enough to measure)."""
    from dynabarn.ros.bridge import RosMaster

    master = RosMaster.start()
    hz = subprocess.Popen(
        ["rostopic", "hz", "-w", "30", "/front/scan"], env=master.env(), stdout=subprocess.PIPE, text=True
    )
    try:
        # The stack starts 2 s late: rostopic (waiting for the topic) subscribes before the first scan.
        late_stack = f"sh -c 'sleep 2; exec {_stack('--delay', '0.03')}'"
        run = _ros("--world", "137", "--master", master.uri, "--no-log", "--launch", late_stack)
        assert run.returncode == 0, run.stderr
    finally:
        hz.terminate()
        out, _ = hz.communicate(timeout=30)
        master.close()
    # rostopic hz prints, per report, the mean of the last window-1 intervals between
    # receptions, each read off /clock. Scans are stamped at whole 0.1 s ticks and the
    # clock moves on in 5 ms steps after each: a reception reads the scan's tick or a
    # later step of its period (later under load, when rostopic handles clock messages
    # before the scan), so the first and last readings of a window are each off by less
    # than a tick and the rate of n intervals lies in 10 n / (n +- 2). Wall-clock intervals
    # (30 ms of stack plus the bridge, about 40 ms) would give about 25 Hz.
    reports = re.findall(r"average rate: ([0-9.]+)\s+min: ([0-9.]+)s max: ([0-9.]+)s .*?window: (\d+)", out)
    assert reports, out
    for rate, _shortest, longest, window in reports:
        n = int(window) - 1
        assert n >= 3, out
        assert 10.0 * n / (n + 2) - 1e-3 <= float(rate) <= 10.0 * n / (n - 2) + 1e-3, (rate, window)
        assert float(longest) <= 0.3 + 0.1, longest  # a scan every period, however late it is read


def test_missing_ros_is_one_line(tmp_path):
    env = {**os.environ, "DYNABARN_ROS_PYTHON": str(tmp_path / "no_python")}
    proc = subprocess.run(
        [sys.executable, "-m", "dynabarn", "ros", "--world", "0", "--no-log"], capture_output=True, text=True, env=env
    )
    assert proc.returncode == 2 and "cannot import rospy" in proc.stderr and proc.stderr.count("\n") == 1


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol
    from dynabarn.recording import McapRecorder
    from dynabarn.sim import run_episode
    from dynabarn.worldset import resolve_world

    path = tmp_path_factory.mktemp("export") / "world_137_dwa.mcap"
    result = run_episode(resolve_world(137), get_planner("dwa"), get_protocol("barn"), observers=[McapRecorder(path)])
    return path, result


def test_rosbag1_export_reads_back_with_rosbag(recording, tmp_path):
    require("rosbags", "ros")
    path, result = recording
    bag = tmp_path / "run.bag"
    proc = subprocess.run(
        [sys.executable, "-m", "dynabarn", "export", str(path), "--bag", str(bag)], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    info = subprocess.run(["rosbag", "info", str(bag)], capture_output=True, text=True, timeout=60)
    assert info.returncode == 0, info.stderr
    for line in ("sensor_msgs/LaserScan", "nav_msgs/Odometry", "tf2_msgs/TFMessage", "geometry_msgs/Twist",
                 "visualization_msgs/MarkerArray", f"/front/scan          {result.n_ticks} msgs"):  # fmt: skip
        assert line in info.stdout, line
    # Debian's rosbag Python API deserialises every message with ROS's own classes.
    script = (
        "import rosbag, json, sys\n"
        "b = rosbag.Bag(sys.argv[1])\n"
        "scans = [m for _, m, _ in b.read_messages(topics=['/front/scan'])]\n"
        "odom = [m for _, m, _ in b.read_messages(topics=['/odometry/filtered'])]\n"
        "res = [json.loads(m.data) for _, m, _ in b.read_messages(topics=['/dynabarn/result'])]\n"
        "obs = [m for _, m, _ in b.read_messages(topics=['/obstacles'])]\n"
        "print(json.dumps([len(scans), len(scans[0].ranges), scans[0].header.frame_id, len(odom),"
        " odom[-1].pose.pose.position.x, res[0]['outcome'], len(obs[0].markers)]))\n"
    )
    read = subprocess.run(["/usr/bin/python3", "-c", script, str(bag)], capture_output=True, text=True, timeout=60)
    assert read.returncode == 0, read.stderr
    n_scans, n_ranges, frame, n_odom, last_x, outcome, n_markers = json.loads(read.stdout)
    assert (n_scans, n_ranges, frame, outcome, n_markers) == (result.n_ticks, 720, "front_laser", "success", 5)
    assert n_odom > n_scans and last_x < -7.5  # near the goal at x = -9


def test_rosbag2_export_reads_back_with_mcap_ros2(recording, tmp_path):
    from mcap.reader import make_reader

    DecoderFactory = require("mcap_ros2.decoder", "test").DecoderFactory
    require("rosbags", "ros")

    path, result = recording
    out = tmp_path / "run_rosbag2"
    proc = subprocess.run(
        [sys.executable, "-m", "dynabarn", "export", str(path), "--format", "rosbag2", "--bag", str(out)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert (out / "metadata.yaml").is_file()
    (mcap_file,) = out.glob("*.mcap")
    counts: dict[str, int] = {}
    with mcap_file.open("rb") as f:
        for schema, channel, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/front/scan" and counts[channel.topic] == 1:
                assert schema.name == "sensor_msgs/msg/LaserScan" and len(msg.ranges) == 720
            if channel.topic == "/dynabarn/result":
                assert json.loads(msg.data)["outcome"] == "success"
    assert counts["/front/scan"] == result.n_ticks and counts["/dynabarn/result"] == 1
    assert counts["/obstacles"] == counts["/cmd_vel"] == result.n_ticks


def test_bench_sweeps_a_ros_stack_with_a_master_per_worker(tmp_path):
    out = tmp_path / "sweep"
    argv = ["--planner", "ros", "--ros-launch", _stack(), "--set", "dynabarn300", "--worlds", "0,5,137"]
    token, env = tagged_environment()
    proc = subprocess.run(
        [sys.executable, "-m", "dynabarn", "bench", *argv, "--trials", "1", "--jobs", "2", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    ros = [r for r in rows if r["planner"] == "ros"]
    assert len(ros) == 3 and {r["outcome"] for r in ros} == {"success"}
    # The blind floor ran beside the stack on the same worlds and seeds.
    assert sorted((r["world"], r["seed"]) for r in rows if r["planner"] == "straight") == sorted(
        (r["world"], r["seed"]) for r in ros
    )
    # The sweep's workers, their masters and stacks end with it (this test's own, not
    # whatever else runs ROS on the machine).
    deadline = time.monotonic() + 30
    while (left := processes_carrying(token)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not left, f"processes of the sweep left behind: {[cmdline(pid) for pid in left]}"


def test_a_stack_that_commands_the_velocity_controller_directly():
    """As the challenge's move_base launch files do: /jackal_velocity_controller/cmd_vel."""
    proc = _ros("--world", "0", "--launch", _stack("/cmd_vel:=/jackal_velocity_controller/cmd_vel"), "--no-log")
    assert proc.returncode == 0, proc.stderr
    assert "SUCCESS" in proc.stdout


def test_paced_at_a_rate_as_gazebo_runs():
    """--rate 4: four times real time with the latest command (no waiting for answers)."""
    proc = _ros("--world", "0", "--launch", _stack(), "--no-log", "--rate", "4", "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["outcome"] == "success" and result["planner_config"]["lockstep"] is False
    assert result["wall_time"] >= result["sim_time"] / 4 * 0.95  # paced, never faster
    # The planner's time leaves out the pacing (25 ms a period here) and the boot.
    assert result["planner_ms_mean"] < 25.0 / 2, result["planner_ms_mean"]


def test_everything_the_bridge_starts_listens_on_loopback_only():
    """The master, the bridge's node and a stack under its environment: no server on another
    interface (roscore's rosout, a roscpp node, listened on all of them)."""
    token, env = tagged_environment()
    proc = subprocess.Popen(
        [sys.executable, "-m", "dynabarn", "ros", "--world", "0", "--no-log", "--launch", _stack("--delay", "0.05")],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    listening: list[str] = []
    try:
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline and len(listening) < 4:
            time.sleep(1.0)
            pids = set(processes_carrying(token))
            ss = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True).stdout.splitlines()
            listening = [line for line in ss if any(f"pid={pid}," in line for pid in pids)]
    finally:
        proc.kill()
        proc.wait()
    assert len(listening) >= 4, listening  # the master, the bridge's node and the stack's servers
    local = [line.split()[3] for line in listening]  # State Recv-Q Send-Q Local Peer Process
    assert all(address.startswith("127.0.0.1:") for address in local), listening


@pytest.mark.parametrize(
    ("stack", "builder", "what", "target", "min_path"),
    [
        ("move_base_dwa", "dynabarn.ros.nav_build", "move_base", "make ros-nav", 3.0),
        ("move_base_teb", "dynabarn.ros.teb_build", "teb_local_planner", "make ros-teb", 2.0),  # TEB: 0.4 m/s
    ],
)
def test_real_stack_starts_and_drives_in_lockstep(stack, builder, what, target, min_path):
    """ROS 1's move_base (built by `make ros-nav`), with the DynaBARN authors' configuration,
    with DWA or with teb_local_planner (`make ros-teb`, TEB's own defaults, as they launch
    it): it starts through the boot (tf2 waits on a running clock) and drives in lockstep.
    Its threads make the exact result vary from run to run, so the test asks that the
    episode is judged (not an error) after it drove a good way towards the goal."""
    import importlib

    from dynabarn.ros.nav_build import default_workspace

    if importlib.import_module(builder).built(default_workspace()) is None:
        pytest.skip(f"{what} is not built in {default_workspace()}: run `{target}`")
    proc = _ros("--world", "137", "--stack", stack, "--no-log", "--json", timeout=600)
    result = json.loads(proc.stdout)
    assert result["outcome"] in ("success", "collision", "timeout"), result["reason"]
    assert result["n_ticks"] >= 20 and result["path_length"] >= min_path, result


def test_teb_build_refuses_a_workspace_without_move_base_and_incomplete_sources(tmp_path, capsys):
    from dynabarn.ros.teb_build import SOURCES, main

    sources = tmp_path / "sources"
    for s in SOURCES[:-1]:  # no g2o
        (sources / s.name).mkdir(parents=True)
    workspace = tmp_path / "ws"
    workspace.mkdir()
    assert main(["--workspace", str(workspace), "--sources", str(sources)]) == 2
    assert "no finished move_base build" in capsys.readouterr().err
    (workspace / "dynabarn-nav.json").write_text('{"commit": "test"}')
    assert main(["--workspace", str(workspace), "--sources", str(sources)]) == 2
    assert "no g2o folder" in capsys.readouterr().err
    assert not (workspace / "src").exists() and not (workspace / "dynabarn-teb.json").exists()


@pytest.mark.parametrize(
    ("stack", "has_move_base", "missing", "target"),
    [
        ("move_base_dwa", False, "move_base is not built", "make ros-nav"),
        ("move_base_teb", True, "teb_local_planner is not built", "make ros-teb"),  # move_base there, TEB not
    ],
)
def test_a_stack_of_ours_not_built_is_one_line(tmp_path, stack, has_move_base, missing, target):
    workspace = tmp_path / "ws"
    workspace.mkdir()
    if has_move_base:
        (workspace / "dynabarn-nav.json").write_text('{"commit": "test"}')
    proc = subprocess.run(
        [sys.executable, "-m", "dynabarn", "ros", "--world", "0", "--stack", stack, "--no-log"],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "DYNABARN_NAV_WS": str(workspace)},
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert missing in proc.stderr and target in proc.stderr


def test_nav_build_takes_a_local_checkout_and_leaves_out_what_a_run_does_not_use(tmp_path):
    """The sources step of `make ros-nav` with NAV_SRC: copied (the checkout untouched),
    amcl, map_server, fake_localization and the metapackage ignored by catkin; a folder
    that is not the navigation stack is refused in one line."""
    from dynabarn.errors import DynabarnError
    from dynabarn.ros.nav_build import LEFT_OUT, _sources, build

    source = tmp_path / "navigation"
    for package in ("move_base", "costmap_2d", *LEFT_OUT):
        (source / package).mkdir(parents=True)
        (source / package / "package.xml").write_text(f"<package><name>{package}</name></package>")
    workspace = tmp_path / "ws"
    with (tmp_path / "log").open("w") as log:
        assert _sources(workspace, source, log) == "local"  # not a git checkout
    with pytest.raises(DynabarnError, match="not a ros-planning/navigation checkout"):
        build(workspace, tmp_path / "ws")
    with pytest.raises(DynabarnError, match="not a ros-planning/navigation checkout"):
        build(tmp_path / "other", tmp_path / "ws")
    assert not (tmp_path / "other").exists()  # refused before anything was written
    copied = workspace / "src" / "navigation"
    assert (copied / "move_base" / "package.xml").is_file()
    assert all((copied / name / "CATKIN_IGNORE").is_file() for name in LEFT_OUT)
    assert not (copied / "costmap_2d" / "CATKIN_IGNORE").exists()
    assert not any((source / name / "CATKIN_IGNORE").exists() for name in LEFT_OUT)
