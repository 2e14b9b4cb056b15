"""Nav2 1.3.4 for `dynabarn-ros --ros 2 --stack nav2_dwb|nav2_mppi`: the controller server
(DWB or MPPI), the planner server with NavFn, the BT navigator (which serves
`navigate_to_pose`, the goal the bridge sends) with Nav2's default behaviour tree (replanning
at 1 Hz; recoveries: clearing the costmaps, spin, wait, back up), the behaviour server that
runs those recoveries, and the lifecycle manager that brings them up, all on the bridge's
/clock (`use_sim_time`). No map and no localisation: every frame is
`odom`, as in the BARN Challenge's odometry-only configuration. The parameters are in
`common.yaml` and the controller's file beside this one.

Arguments: controller (dwb or mppi, default dwb); params (a further parameter file loaded
last, default none).
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

HERE = os.path.dirname(os.path.abspath(__file__))
SERVERS = ("controller_server", "planner_server", "behavior_server", "bt_navigator")


def _nodes(context):
    controller = LaunchConfiguration("controller").perform(context)
    if controller not in ("dwb", "mppi"):
        raise RuntimeError(f"controller:={controller}: use dwb or mppi")
    extra = LaunchConfiguration("params").perform(context)
    files = [os.path.join(HERE, "common.yaml"), os.path.join(HERE, f"{controller}.yaml"), *([extra] if extra else [])]
    # Nav2's default tree, named: what `nav2_bringup` runs.
    tree = os.path.join(
        get_package_share_directory("nav2_bt_navigator"),
        "behavior_trees",
        "navigate_to_pose_w_replanning_and_recovery.xml",
    )
    sim_time = {"use_sim_time": True}
    nodes = [
        Node(package="nav2_controller", executable="controller_server", output="screen", parameters=[*files, sim_time]),
        Node(package="nav2_planner", executable="planner_server", output="screen", parameters=[*files, sim_time]),
        Node(package="nav2_behaviors", executable="behavior_server", output="screen", parameters=[*files, sim_time]),
        Node(
            package="nav2_bt_navigator",
            executable="bt_navigator",
            output="screen",
            parameters=[*files, sim_time, {"default_nav_to_pose_bt_xml": tree}],
        ),
        Node(
            package="nav2_lifecycle_manager",
            executable="lifecycle_manager",
            name="lifecycle_manager_navigation",
            output="screen",
            parameters=[sim_time, {"autostart": True, "node_names": list(SERVERS)}],
        ),
    ]
    return nodes


def generate_launch_description():
    return LaunchDescription(
        [
            DeclareLaunchArgument("controller", default_value="dwb", description="dwb or mppi"),
            DeclareLaunchArgument("params", default_value="", description="a further parameter file, loaded last"),
            OpaqueFunction(function=_nodes),
        ]
    )
