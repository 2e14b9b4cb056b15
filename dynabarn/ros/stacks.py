"""Navigation stacks `dynabarn-ros --stack NAME` starts: ROS 1's move_base, built from
source by `make ros-nav` (`nav_build`; TEB by `make ros-teb`, `teb_build`), with the launch and parameter files of
`dynabarn/ros/launch/` (each value with its source in the BARN Challenge's branches)."""

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
    },
    check=instances_of(Stack),
)
"""The move_base stacks `--stack` starts by name; `STACKS.register(Stack(...), name=...)` adds one."""


def stack_command(name: str, workspace: Path | None = None) -> list[str]:
    """The command that starts stack `name` from the built workspace (one clear error when
    the stack is unknown or move_base is not built)."""
    STACKS.get_item(name)  # one line for an unknown name, with the nearest
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
    args = " ".join(f"{k}:={shlex.quote(v.format(launch=LAUNCH))}" for k, v in stack.args)
    # The workspace's environment (ROS_PACKAGE_PATH, libraries) for roslaunch and move_base.
    setup = shlex.quote(str(workspace / "devel" / "setup.bash"))
    line = f"source {setup} && exec roslaunch {shlex.quote(str(LAUNCH / stack.launch))} {args}".rstrip()
    return ["bash", "-c", line]
