"""The controller of the tests' ROS stacks (`ros_stack.py` on rospy, `ros2_stack.py` on
rclpy), in one place: both bridges must see the same decisions for the same messages (a
test compares their episodes). Plain Python: it runs on Debian's /usr/bin/python3."""

from __future__ import annotations

import math
import time


def command(scan, odom, goal: tuple[float, float] | None, *, delay: float = 0.0) -> tuple[float, float] | None:
    """The stack's answer to a scan and its odometry: none until there is a goal (as
    move_base and Nav2 command nothing without one), then `steer`; `delay` seconds of
    thinking first (a slow stack).

    Silence before the goal is what makes an episode the same on every run: the bridge
    starts the episode at the stack's first command, and a stack that answered before its
    goal arrived would start driving at whichever tick the goal's delivery happened to
    land on (a race between two topics that lockstep cannot order)."""
    if goal is None:
        return None
    if delay:
        time.sleep(delay)
    return steer(scan, odom, goal)


def steer(scan, odom, goal: tuple[float, float]) -> tuple[float, float]:
    """(v, w) towards `goal` (odometry frame) from a LaserScan and the Odometry of its
    stamp: at the goal's heading, away from close returns within +-0.5 rad ahead."""
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    yaw = 2.0 * math.atan2(q.z, q.w)
    heading = math.atan2(goal[1] - p.y, goal[0] - p.x) - yaw
    heading = math.atan2(math.sin(heading), math.cos(heading))
    n, ranges = len(scan.ranges), list(scan.ranges)
    lo = max(0, math.ceil((-0.5 - scan.angle_min) / scan.angle_increment))  # the beams within +-0.5 rad
    hi = min(n, math.floor((0.5 - scan.angle_min) / scan.angle_increment) + 1)
    left = min(ranges[n // 2 : n // 2 + n // 4], default=scan.range_max)
    right = min(ranges[n // 4 : n // 2], default=scan.range_max)
    nearest = min(ranges[lo:hi], default=scan.range_max)
    v = 2.0 if nearest > 2.0 else max(0.3, nearest - 0.5)
    w = max(-3.0, min(3.0, 2.0 * heading + (0.8 if nearest < 1.5 and right < left else 0.0)))
    return v, w


class StampPairs:
    """Each scan paired with the odometry of the same stamp, whichever comes first: `decide`
    is called once per pair (so a stack answers the same messages the same way, whatever
    order the middleware delivers them in)."""

    def __init__(self, decide) -> None:
        self.decide = decide
        self.scans: dict = {}
        self.odoms: dict = {}

    def scan(self, stamp, msg) -> None:
        self.scans[stamp] = msg
        self._pair(stamp)

    def odom(self, stamp, msg) -> None:
        self.odoms[stamp] = msg
        self._pair(stamp)

    def _pair(self, stamp) -> None:
        scan, odom = self.scans.get(stamp), self.odoms.get(stamp)
        if scan is not None and odom is not None:
            del self.scans[stamp], self.odoms[stamp]
            self.decide(scan, odom)
