"""A small ROS 1 navigation stack for the tests of `dynabarn-ros`, written as a BARN
Challenge entry would be: a rospy node on /front/scan and /odometry/filtered that drives to
the goal from /move_base_simple/goal, publishing /cmd_vel once per scan, plus an actionlib
`move_base` server (the challenge's run.py sends its goal that way).

Run with Debian's Python (`/usr/bin/python3 tests/ros_stack.py`). The controller steers at
the goal and away from close returns in front; deterministic for the same messages (each
scan is paired with the odometry of the same stamp, whatever order they arrive in).

Flags: --die-after N (exit after N scans: a stack that crashes), --mute (never answer),
--delay S (think S seconds per scan: a slow stack).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time


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
    args = parser.parse_args(rospy.myargv(sys.argv)[1:])
    rospy.init_node("test_stack")
    cmd_pub = rospy.Publisher("/cmd_vel", Twist, queue_size=10, tcp_nodelay=True)
    state = {"goal": None, "odom": {}, "scans": {}, "n": 0}

    def on_goal(msg: PoseStamped) -> None:
        if args.goal_from == "topic":
            state["goal"] = (msg.pose.position.x, msg.pose.position.y)

    def decide(scan: LaserScan, odom: Odometry) -> None:
        state["n"] += 1
        if args.die_after and state["n"] > args.die_after:
            os._exit(3)  # a crash: no clean shutdown
        if args.mute:
            return
        if args.delay:
            time.sleep(args.delay)
        if state["goal"] is None:  # no goal yet: stand still, but answer
            cmd_pub.publish(Twist())
            return
        p, q = odom.pose.pose.position, odom.pose.pose.orientation
        yaw = 2.0 * math.atan2(q.z, q.w)
        gx, gy = state["goal"]
        heading = math.atan2(gy - p.y, gx - p.x) - yaw
        heading = math.atan2(math.sin(heading), math.cos(heading))
        n, ranges = len(scan.ranges), scan.ranges
        lo = max(0, math.ceil((-0.5 - scan.angle_min) / scan.angle_increment))  # the beams within +-0.5 rad
        hi = min(n, math.floor((0.5 - scan.angle_min) / scan.angle_increment) + 1)
        left = min(ranges[n // 2 : n // 2 + n // 4], default=scan.range_max)
        right = min(ranges[n // 4 : n // 2], default=scan.range_max)
        nearest = min(ranges[lo:hi], default=scan.range_max)
        cmd = Twist()
        cmd.linear.x = 2.0 if nearest > 2.0 else max(0.3, nearest - 0.5)
        cmd.angular.z = max(-3.0, min(3.0, 2.0 * heading + (0.8 if nearest < 1.5 and right < left else 0.0)))
        cmd_pub.publish(cmd)

    def pair(stamp) -> None:
        scan, odom = state["scans"].get(stamp), state["odom"].get(stamp)
        if scan is not None and odom is not None:
            del state["scans"][stamp], state["odom"][stamp]
            decide(scan, odom)

    def on_scan(msg: LaserScan) -> None:
        state["scans"][msg.header.stamp] = msg
        pair(msg.header.stamp)

    def on_odom(msg: Odometry) -> None:
        state["odom"][msg.header.stamp] = msg
        pair(msg.header.stamp)

    def on_action(goal) -> None:  # the move_base action: drive there, succeed when close
        pose = goal.target_pose.pose.position
        state["goal"] = (pose.x, pose.y)
        server.set_succeeded(MoveBaseResult())

    server = actionlib.SimpleActionServer("move_base", MoveBaseAction, execute_cb=on_action, auto_start=False)
    server.start()  # first, as move_base does: the bridge looks for it once the scan is heard
    rospy.Subscriber("/move_base_simple/goal", PoseStamped, on_goal, queue_size=1)
    rospy.Subscriber("/odometry/filtered", Odometry, on_odom, queue_size=50, tcp_nodelay=True)
    rospy.Subscriber("/front/scan", LaserScan, on_scan, queue_size=50, tcp_nodelay=True)

    rospy.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
