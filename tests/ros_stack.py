"""A small ROS 1 navigation stack for the tests of `dynabarn-ros`, written as a BARN
Challenge entry would be: a rospy node on /front/scan and /odometry/filtered that drives to
the goal from /move_base_simple/goal, publishing /cmd_vel once per scan, plus an actionlib
`move_base` server (the challenge's run.py sends its goal that way).

Run with Debian's Python (`/usr/bin/python3 tests/ros_stack.py`). The controller steers at
the goal and away from close returns in front; deterministic for the same messages (each
scan is paired with the odometry of the same stamp, whatever order they arrive in).

Flags: --die-after N (exit after N scans: a stack that crashes), --mute (never answer),
--mute-after N (answer N scans, then never again), --delay S (think S seconds per scan: a
slow stack), --like-move-base (start and run as move_base does: wait through tf2 for
odom -> base_link before subscribing to the scan, then publish only from a 20 Hz timer on
ROS time, from the latest scan and odometry, skipping `--plan-cycles` cycles after the
goal and three of every 40 after that, as while its global planner runs).
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # also in safe-path mode
from stack_controller import StampPairs, command


def main() -> int:
    import actionlib
    import rospy
    from geometry_msgs.msg import PoseStamped, Twist
    from move_base_msgs.msg import MoveBaseAction, MoveBaseResult
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan

    parser = argparse.ArgumentParser()
    parser.add_argument("--die-after", type=int, default=0)
    parser.add_argument("--mute", action="store_true")
    parser.add_argument("--delay", type=float, default=0.0, help="seconds of thinking per scan (a slow stack)")
    parser.add_argument("--goal-from", choices=["topic", "action"], default="topic")
    parser.add_argument("--mute-after", type=int, default=0)
    parser.add_argument("--like-move-base", action="store_true")
    parser.add_argument("--plan-cycles", type=int, default=4)
    args = parser.parse_args(rospy.myargv(sys.argv)[1:])
    rospy.init_node("test_stack")
    cmd_pub = rospy.Publisher("/cmd_vel", Twist, queue_size=10, tcp_nodelay=True)
    state = {"goal": None, "n": 0}

    def on_goal(msg: PoseStamped) -> None:
        if args.goal_from == "topic":
            state["goal"] = (msg.pose.position.x, msg.pose.position.y)

    def decide(scan: LaserScan, odom: Odometry) -> None:
        state["n"] += 1
        if args.die_after and state["n"] > args.die_after:
            os._exit(3)  # a crash: no clean shutdown
        if args.mute or (args.mute_after and state["n"] > args.mute_after):
            return
        answer = command(scan, odom, state["goal"], delay=args.delay)
        if answer is None:  # no goal yet: silent, as move_base and Nav2 are
            return
        cmd = Twist()
        cmd.linear.x, cmd.angular.z = answer
        cmd_pub.publish(cmd)

    pairs = StampPairs(decide)

    def on_action(goal) -> None:  # the move_base action: drive there, succeed when close
        pose = goal.target_pose.pose.position
        state["goal"] = (pose.x, pose.y)
        server.set_succeeded(MoveBaseResult())

    server = actionlib.SimpleActionServer("move_base", MoveBaseAction, execute_cb=on_action, auto_start=False)
    server.start()  # first, as move_base does: the bridge looks for it once the scan is heard
    rospy.Subscriber("/move_base_simple/goal", PoseStamped, on_goal, queue_size=1)
    if args.like_move_base:
        _run_like_move_base(args, state, decide)
    else:
        on_odom = lambda m: pairs.odom(m.header.stamp, m)  # noqa: E731
        on_scan = lambda m: pairs.scan(m.header.stamp, m)  # noqa: E731
        rospy.Subscriber("/odometry/filtered", Odometry, on_odom, queue_size=50, tcp_nodelay=True)
        rospy.Subscriber("/front/scan", LaserScan, on_scan, queue_size=50, tcp_nodelay=True)
    rospy.spin()
    return 0


def _run_like_move_base(args, state: dict, decide) -> None:
    """move_base's start-up and loop: Costmap2DROS waits (on ROS time) for odom -> base_link
    before it subscribes to the scan; the controller runs from a timer on ROS time."""
    import rospy
    import tf2_ros
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan

    buffer = tf2_ros.Buffer()
    tf2_ros.TransformListener(buffer)
    while not buffer.can_transform("odom", "base_link", rospy.Time(0), rospy.Duration(0.1)):
        pass  # blocks for as long as /clock is absent or frozen, as tf2's waits do in move_base
    latest: dict = {}
    rospy.Subscriber("/odometry/filtered", Odometry, lambda m: latest.__setitem__("odom", m), queue_size=1)
    rospy.Subscriber("/front/scan", LaserScan, lambda m: latest.__setitem__("scan", m), queue_size=1)
    cycles = {"n": 0}

    def control(_event) -> None:
        if state["goal"] is None or "scan" not in latest or "odom" not in latest:
            return
        cycles["n"] += 1
        n = cycles["n"]
        if n <= args.plan_cycles or n % 40 in (1, 2, 3):  # planning: nothing on /cmd_vel
            return
        decide(latest["scan"], latest["odom"])

    rospy.Timer(rospy.Duration(0.05), control)


if __name__ == "__main__":
    sys.exit(main())
