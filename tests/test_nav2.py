"""Real Nav2 in the loop (`dynabarn-ros --stack nav2_dwb|nav2_mppi`): the overlay `make nav2`
builds over the ROS 2 core, and Nav2's controller server (DWB, MPPI), planner server and BT
navigator driving world 137 through the ROS 2 bridge. Where Nav2 is not built (CI cannot
fetch its sources) those tests skip with the command that builds it; the build's own checks
(its sources, its refusals) and the stacks' refusals run everywhere."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dynabarn.errors import DynabarnError, NotInstalledHere
from dynabarn.ros import colcon, nav2_build
from dynabarn.ros.stacks import STACKS, stack_command

BIN = Path(sys.executable).parent


def _nav2() -> Path:
    workspace = nav2_build.default_workspace()
    if nav2_build.built(workspace) is None:
        pytest.skip(f"Nav2 is not built in {workspace}: make nav2 NAV2_SRC=<folder of the fetched repositories>")
    return workspace


def test_the_repositories_are_nav2s_jazzy_release_and_a_wrong_folder_is_one_line(tmp_path):
    text = colcon.repos_file(nav2_build.REPOSITORIES)
    assert text.count("type: git") == len(nav2_build.REPOSITORIES) == 8
    assert "    url: https://github.com/ros-navigation/navigation2.git\n    version: 1.3.4" in text
    (tmp_path / "navigation2" / "nav2_util").mkdir(parents=True)
    (tmp_path / "navigation2" / "nav2_util" / "package.xml").write_text(
        "<package><name>nav2_util</name><version>1.3.13</version></package>"
    )
    with pytest.raises(DynabarnError, match=r"not the sources of Nav2 1\.3\.4: navigation2 \(1\.3\.13, not 1\.3\.4\)"):
        nav2_build.find_sources(tmp_path)  # the core's check, with Nav2's repositories
    out = subprocess.run(
        [str(BIN / "python"), "-m", "dynabarn.ros.nav2_build", "--source", str(tmp_path / "nowhere"),
         "--workspace", str(tmp_path / "ws")],
        capture_output=True,
        text=True,
    )  # fmt: skip
    assert out.returncode == 2 and out.stderr.strip().splitlines() == [
        f"error: {tmp_path / 'nowhere'}: no such folder (fetch the sources: python -m dynabarn.ros.nav2_build --repos)"
    ]
    out = subprocess.run(
        [str(BIN / "python"), "-m", "dynabarn.ros.nav2_build", "--repos"], capture_output=True, text=True
    )
    assert out.returncode == 0 and out.stdout == text


def test_a_nav2_stack_without_nav2_is_one_line_naming_the_command(tmp_path, monkeypatch):
    monkeypatch.setenv(nav2_build.WORKSPACE_ENV, str(tmp_path / "no_nav2"))
    with pytest.raises(NotInstalledHere, match=r"Nav2 is not built in .*no_nav2: run `make nav2 NAV2_SRC="):
        stack_command("nav2_dwb")
    assert STACKS["nav2_dwb"].ros == STACKS["nav2_mppi"].ros == 2 and STACKS["move_base_dwa"].ros == 1


def test_a_stack_on_the_other_ros_is_refused():
    from dynabarn.ros.bridge_config import BridgeConfig

    with pytest.raises(TypeError, match="stack 'nav2_mppi' runs on ROS 2, not ROS 1"):
        BridgeConfig(stack="nav2_mppi").check("ros")
    out = subprocess.run(
        [str(BIN / "dynabarn-ros"), "--world", "137", "--stack", "nav2_dwb", "--ros", "1", "--no-log"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2 and out.stderr.strip().splitlines()[-1].endswith(
        "--stack nav2_dwb runs on ROS 2: leave out --ros 1"
    )


def test_the_launch_file_and_parameters_are_installed_with_the_package():
    from dynabarn.ros.stacks import LAUNCH

    folder = LAUNCH / "nav2"
    assert {p.name for p in folder.iterdir()} >= {"nav2_dynabarn.launch.py", "common.yaml", "dwb.yaml", "mppi.yaml"}
    import yaml

    dwb = yaml.safe_load((folder / "dwb.yaml").read_text())["controller_server"]["ros__parameters"]["FollowPath"]
    from dynabarn.planners.dwa import DWAConfig

    ours = DWAConfig()  # DWB as close to our dwa preset as the planners allow: the same limits and weights
    assert (dwb["max_vel_x"], dwb["max_vel_theta"], dwb["acc_lim_x"], dwb["acc_lim_theta"]) == (
        ours.max_vel_x, ours.max_vel_theta, ours.acc_lim_x, ours.acc_lim_theta
    )  # fmt: skip
    assert (dwb["sim_time"], dwb["vx_samples"], dwb["vtheta_samples"]) == (
        ours.sim_time,
        ours.vx_samples,
        ours.vth_samples,
    )
    assert (dwb["PathDist.scale"], dwb["GoalDist.scale"], dwb["BaseObstacle.scale"]) == (
        ours.path_distance_bias, ours.goal_distance_bias, ours.occdist_scale
    )  # fmt: skip


def test_the_built_overlay_says_what_it_holds():
    workspace = _nav2()
    record = nav2_build.built(workspace)
    assert record["nav2"] == "1.3.4" and set(nav2_build.PACKAGES) <= set(record["packages"])
    assert "behaviortree_cpp" in record["packages"] and record["install_bytes"] > 10e6


@pytest.mark.parametrize("stack", ["nav2_dwb", "nav2_mppi"])
def test_nav2_drives_world_137_to_an_outcome(stack, tmp_path):
    """Real Nav2 on the bridge: the lifecycle manager brings the servers up on the bridge's
    clock, the BT navigator takes the goal through `navigate_to_pose`, the controller's
    /cmd_vel moves the robot; the episode ends in success or a collision (never an error),
    and its recording and the stack's log are written."""
    _nav2()
    log = tmp_path / "nav2.mcap"
    out = subprocess.run(
        [str(BIN / "dynabarn-ros"), "--stack", stack, "--world", "137", "--log", str(log), "--json",
         "--ready-timeout", "120"],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "PYTHONSAFEPATH": "1"},
    )  # fmt: skip
    assert out.returncode in (0, 1), out.stderr[-2000:]
    result = json.loads(out.stdout)
    assert result["outcome"] in ("success", "collision"), result
    assert result["planner_config"]["stack"] == stack and result["planner_config"]["ros"] == 2
    assert result["n_ticks"] > 20 and log.is_file()
    assert result["periods_after_navigation_ended"] >= 0 and result["bridge_ms_per_tick"] > 0
    stack_log = Path(result["stack_log"]).read_text()
    assert "Managed nodes are active" in stack_log  # the lifecycle manager brought Nav2 up


def test_a_nav2_stack_may_boot_and_stay_silent_longer_unless_limits_are_given():
    """Nav2's recoveries send no /cmd_vel (its Wait: 5 s of ROS time, held period by period),
    and it brings up its servers one by one before its first: its stacks carry their own
    silence and boot limits, which explicit ones override; the bridge's settings are checked
    against the ranges the command gives them."""
    from dynabarn.interfaces import config_from_kwargs
    from dynabarn.ros.bridge_config import BridgeConfig
    from dynabarn.ros.stacks import NAV2_BOOT, NAV2_SILENCE

    assert BridgeConfig().silence_limit == 10.0 and BridgeConfig(stack="move_base_dwa").silence_limit == 10.0
    assert BridgeConfig(stack="nav2_dwb", ros=2).silence_limit == NAV2_SILENCE == 60.0
    assert BridgeConfig(stack="nav2_dwb", ros=2, timeout=5.0).silence_limit == 5.0
    assert BridgeConfig().boot_limit == 30.0 and BridgeConfig(stack="move_base_teb").boot_limit == 30.0
    assert BridgeConfig(stack="nav2_mppi", ros=2).boot_limit == NAV2_BOOT == 90.0
    assert BridgeConfig(stack="nav2_mppi", ros=2, ready_timeout=5.0).boot_limit == 5.0
    with pytest.raises(ValueError, match="ros2_bag"):
        BridgeConfig(ros2_bag="/tmp/x")  # rosbag2 is ROS 2's
    for key, bad, message in (
        ("timeout", "x", "expected a number"),
        ("timeout", -1, r"out of range \[0.1, 600\]"),
        ("grace", 0, r"out of range \[0.001, 600\]"),
        ("ready_timeout", 0, r"out of range \[0.1, 600\]"),
    ):
        with pytest.raises(TypeError, match=f"ros {key}={bad!r}: {message}"):
            config_from_kwargs(BridgeConfig, {key: bad}, "ros")
    assert config_from_kwargs(BridgeConfig, {"timeout": None}, "ros").timeout is None


def test_nothing_of_a_stacks_process_group_outlives_it():
    """A stack's leader that ends on SIGINT while a node of it ignores SIGINT and SIGTERM
    (as a Nav2 server hung in its shutdown, left by `ros2 launch`): `stop_process` leaves
    nothing of the group running."""
    import time

    from dynabarn.processes import die_with_parent
    from dynabarn.ros.master import stop_process

    leader = subprocess.Popen(
        ["bash", "-c", "(trap '' INT TERM; exec sleep 300) & echo $!; wait"],
        stdout=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=die_with_parent(),
    )
    child = int(leader.stdout.readline())
    time.sleep(0.2)  # the child has set its dispositions and exec'd sleep
    stop_process(leader, timeout=5.0)
    assert leader.poll() is not None
    deadline = time.monotonic() + 5.0
    while _running(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _running(child), f"process {child} of the stack's group outlived it"


def _running(pid: int) -> bool:
    """Whether `pid` runs (a zombie, killed and waiting to be reaped, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def test_a_navigation_the_stack_aborts_leaves_the_robot_standing(tmp_path):
    """A stack that serves Nav2's `navigate_to_pose`, follows the goal, then aborts it and
    commands nothing more (as Nav2 does when its recoveries are spent): the bridge offers
    the goal through the action, the robot stands from the abort on and the episode runs to
    its end, never an error for the silence."""
    _nav2()  # nav2_msgs, for the action
    out = subprocess.run(
        [str(BIN / "dynabarn-ros"), "--ros", "2", "--world", "137", "--no-log", "--json", "--timeout", "5",
         "--launch", f"/usr/bin/python3 {Path(__file__).resolve().parent / 'ros2_stack.py'} --abort-after 3"],
        capture_output=True,
        text=True,
        timeout=600,
    )  # fmt: skip
    result = json.loads(out.stdout)
    assert result["outcome"] in ("timeout", "collision"), result["reason"]
    assert result["periods_after_navigation_ended"] > 0, result
    assert result["sim_time"] > 3.5 and result["path_length"] < 2.0 * 3.5, result  # it stood after 3 s
