"""A small ROS 2 navigation stack for the tests of `dynabarn-ros --ros 2`, written as a Nav2
user's node would be: rclpy, `use_sim_time`, the scan with the sensor-data QoS, the goal
from `/goal_pose` (transient-local, as the bridge latches it), /cmd_vel once per scan.

Run with Debian's Python in the ROS 2 prefix's environment (the bridge starts it so). The
controller is `ros_stack.py`'s: it steers at the goal and away from close returns in
front, deterministic for the same messages (each scan paired with the odometry of the
same stamp). Flags: --mute (never answer), --delay S (think S seconds per scan).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # also in safe-path mode
from stack_controller import StampPairs, command


def main() -> int:
    import rclpy
    from geometry_msgs.msg import PoseStamped, Twist
    from nav_msgs.msg import Odometry
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
    from sensor_msgs.msg import LaserScan

    rclpy.init(args=sys.argv)
    parser = argparse.ArgumentParser()
    parser.add_argument("--mute", action="store_true")
    parser.add_argument("--delay", type=float, default=0.0, help="seconds of thinking per scan (a slow stack)")
    parser.add_argument(
        "--abort-after",
        type=float,
        default=None,
        help="serve Nav2's navigate_to_pose (nav2_msgs) and abort it after S seconds of ROS time, then command "
        "nothing more: a Nav2 that gives up",
    )
    args = parser.parse_args(rclpy.utilities.remove_ros_args(sys.argv)[1:])
    node = rclpy.create_node("test_stack", parameter_overrides=[Parameter("use_sim_time", value=True)])
    cmd_pub = node.create_publisher(Twist, "/cmd_vel", 10)
    state = {"goal": None}

    def on_goal(msg: PoseStamped) -> None:
        state["goal"] = (msg.pose.position.x, msg.pose.position.y)

    def decide(scan: LaserScan, odom: Odometry) -> None:
        if args.mute or state.get("gave_up"):
            return
        answer = command(scan, odom, state["goal"], delay=args.delay)
        if answer is None:  # no goal yet: silent, as move_base and Nav2 are
            return
        cmd = Twist()
        cmd.linear.x, cmd.angular.z = answer
        cmd_pub.publish(cmd)

    def key(msg) -> tuple[int, int]:
        return (msg.header.stamp.sec, msg.header.stamp.nanosec)

    pairs = StampPairs(decide)

    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(PoseStamped, "/goal_pose", on_goal, latched)
    node.create_subscription(Odometry, "/odometry/filtered", lambda m: pairs.odom(key(m), m), 50)
    node.create_subscription(LaserScan, "/front/scan", lambda m: pairs.scan(key(m), m), qos_profile_sensor_data)
    executor = rclpy.executors.SingleThreadedExecutor()
    if args.abort_after is not None:  # the action's execution waits in its own thread while scans come
        serve_and_abort(node, state, args.abort_after)
        executor = rclpy.executors.MultiThreadedExecutor()
    executor.add_node(node)
    with contextlib.suppress(KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        executor.spin()
    return 0


def serve_and_abort(node, state: dict, after: float) -> None:
    """`navigate_to_pose` as Nav2's BT navigator offers it: the goal accepted and followed
    (the controller above), then, `after` seconds of ROS time later, aborted, and no command
    sent again."""
    import time

    from nav2_msgs.action import NavigateToPose
    from rclpy.action import ActionServer
    from rclpy.callback_groups import ReentrantCallbackGroup

    def execute(handle):
        state["goal"] = (handle.request.pose.pose.position.x, handle.request.pose.pose.position.y)
        start = node.get_clock().now()
        while (node.get_clock().now() - start).nanoseconds < after * 1e9:
            time.sleep(0.01)
        state["gave_up"] = True
        handle.abort()
        return NavigateToPose.Result()

    group = ReentrantCallbackGroup()
    state["server"] = ActionServer(node, NavigateToPose, "navigate_to_pose", execute, callback_group=group)


if __name__ == "__main__":
    sys.exit(main())
