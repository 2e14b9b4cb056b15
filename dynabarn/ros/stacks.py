"""Navigation stacks `dynabarn-ros --stack NAME` starts: ROS 1's move_base, built from
source by `make ros-nav` (`nav_build`; TEB by `make ros-teb`, `teb_build`), with the launch and parameter files of
`dynabarn/ros/launch/` (each value with its source in the BARN Challenge's branches); and ROS 2's Nav2
(DWB, MPPI), built by `make nav2` (`nav2_build`), with `dynabarn/ros/launch/nav2/`."""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path

from dynabarn.errors import NotInstalledHere
from dynabarn.registry import Registry, instances_of
from dynabarn.ros.nav_build import built, default_workspace
from dynabarn.ros.teb_build import built as teb_built

LAUNCH = Path(__file__).resolve().parent / "launch"


@dataclass(frozen=True)
class Stack:
    launch: str
    """The launch file in `dynabarn/ros/launch/`."""
    args: tuple[tuple[str, str], ...] = ()
    """roslaunch arguments; `{launch}` in a value is the launch folder."""
    about: str = ""
    control_rate: float = 20.0
    """[Hz] move_base's controller_frequency (dyna_barn/move_base.yaml): its loop's timer."""
    teb: bool = False
    """Needs teb_local_planner (`make ros-teb`) in the workspace too."""
    ros: int = 1
    """The ROS it runs on: 1 (move_base, `make ros-nav`) or 2 (Nav2, `make nav2`)."""
    timeout: float = 10.0
    """Wall seconds the stack may send no /cmd_vel before the episode is an error (the
    bridge's `timeout` where none is given)."""
    boot: float = 30.0
    """Wall seconds the stack may take to start (the bridge's `ready_timeout` where none is
    given)."""


def _nav2(controller: str, about: str) -> Stack:
    """A Nav2 stack (`make nav2`) with its controller server running `controller`. Nav2's
    controller server, costmaps and BT navigator run their loops on wall-clock rates
    (rclcpp::WallRate), not on ROS time: the bridge takes the first /cmd_vel after each scan
    (control_rate 0) rather than holding the clock for a timer."""
    return Stack(
        "nav2/nav2_dynabarn.launch.py",
        (("controller", controller),),
        about=f"{about} (ROS 2; `make nav2`)",
        control_rate=0.0,
        ros=2,
        timeout=NAV2_SILENCE,
        boot=NAV2_BOOT,
    )


NAV2_SILENCE = 60.0
"""[s] Nav2's recoveries send no /cmd_vel while they run (its default tree's Wait: 5 s of ROS
time, which lockstep holds period by period, each after its grace)."""

NAV2_BOOT = 90.0
"""[s] Nav2 brings up five lifecycle servers, a BT navigator's plugins and two costmaps
before its first /cmd_vel: about 8 s here when idle, over 30 s on this machine under two
other Nav2 runs (one episode of the sweeps ended as an error at 30)."""

STACKS: Registry[Stack] = Registry(
    "ROS stack",
    {
        "move_base_dwa": Stack(
            "move_base_dwa.launch",
            about="move_base, navfn and base_local_planner's DWA as the DynaBARN authors configured them "
            "(the BARN Challenge's dyna_barn branch)",
        ),
        "move_base_dwa_barn": Stack(
            "move_base_dwa.launch",
            (("overrides", "{launch}/barn_main/overrides.yaml"),),
            about="the same with the BARN Challenge main branch's planner values (0.5 m/s, 6 x 20 samples; the "
            "dyna_barn global costmap, since main's puts the goal off it)",
        ),
        "move_base_teb": Stack(
            "move_base_teb.launch",
            about="move_base, navfn and teb_local_planner with its ROS defaults, as the DynaBARN authors launch it "
            "(the BARN Challenge's dyna_barn branch; `make ros-teb`)",
            teb=True,
        ),
        "nav2_dwb": _nav2(
            "dwb", "Nav2 1.3.4 with DWB configured as our `dwa`, NavFn and the BT navigator replanning at 1 Hz"
        ),
        "nav2_mppi": _nav2(
            "mppi", "Nav2 1.3.4 with MPPI's defaults at the Jackal's limits, NavFn and the BT navigator"
        ),
    },
    check=instances_of(Stack),
)
"""The stacks `--stack` starts by name; `STACKS.register(Stack(...), name=...)` adds one."""


def stack_command(name: str, workspace: Path | None = None) -> list[str]:
    """The command that starts stack `name` from the built workspace (one clear error when
    the stack is unknown or move_base or Nav2 is not built)."""
    STACKS.get_item(name)  # one line for an unknown name, with the nearest
    if STACKS[name].ros == 2:
        return _launch_command(STACKS[name], nav2_setup(workspace), "ros2 launch")
    workspace = (workspace or default_workspace()).expanduser()
    if built(workspace) is None:
        raise NotInstalledHere(
            f"move_base is not built in {workspace}: run `make ros-nav` (about 6 minutes on 2 cores)", "make ros-nav"
        )
    stack = STACKS[name]
    if stack.teb and teb_built(workspace) is None:
        raise NotInstalledHere(
            f"teb_local_planner is not built in {workspace}: run `make ros-teb` (about 20 minutes on 2 cores)",
            "make ros-teb",
        )
    # The workspace's environment (ROS_PACKAGE_PATH, libraries) for roslaunch and move_base.
    return _launch_command(stack, workspace / "devel" / "setup.bash", "roslaunch")


def nav2_setup(workspace: Path | None = None) -> Path:
    """The `setup.bash` of the Nav2 overlay `make nav2` built (over the ROS 2 core), in which
    the bridge node and a Nav2 stack run; one clear error when there is none."""
    from dynabarn.ros import colcon, nav2_build

    workspace = (workspace or nav2_build.default_workspace()).expanduser()
    setup = colcon.setup_script(workspace)
    if nav2_build.built(workspace) is None or not setup.is_file():
        raise NotInstalledHere(
            f"Nav2 is not built in {workspace}: run `make nav2 NAV2_SRC=<folder of the fetched repositories>` "
            "(about 16 minutes on 2 cores, over `make ros2-core`)",
            "make nav2 NAV2_SRC=<folder>",
        )
    return setup


def _launch_command(stack: Stack, setup: Path, launcher: str) -> list[str]:
    """`launcher` (roslaunch, ros2 launch) on the stack's launch file with its arguments, in
    the environment `setup` gives."""
    args = " ".join(f"{k}:={shlex.quote(v.format(launch=LAUNCH))}" for k, v in stack.args)
    line = f"source {shlex.quote(str(setup))} && exec {launcher} {shlex.quote(str(LAUNCH / stack.launch))} {args}"
    return ["bash", "-c", line.rstrip()]
