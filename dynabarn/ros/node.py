"""The ROS side of `dynabarn-ros`: a rospy node that makes the simulation look like the BARN
Challenge's Gazebo to a ROS 1 navigation stack.

Runs on Debian's `/usr/bin/python3` (where Debian's rospy lives), as its own process, and
imports nothing of dynabarn: the simulation (the project's Python, with MuJoCo) talks to it
over stdin/stdout in length-prefixed frames (`Frame` below, struct-packed, little endian):

    sim -> node  'O' observation: t, x, y, yaw, v, w, n, ranges[n] (float64 x 7 + float32 x n)
                 'G' goal: x, y, yaw (published once, latched, before the first observation)
                 'E' end: outcome text (published on /collision when it is a collision)
    node -> sim  'C' command: v, w, answered (float64, float64, uint8)
                 'R' ready: the stack is subscribed (or the wait timed out: answered 0)

Published, as the challenge's simulation does: /clock (with /use_sim_time set), /front/scan
(sensor_msgs/LaserScan, frame front_laser), /odometry/filtered (nav_msgs/Odometry, odom ->
base_link), /tf (odom -> base_link) and /tf_static (base_link -> front_laser), the goal on
/move_base_simple/goal (geometry_msgs/PoseStamped, frame odom), /collision (std_msgs/Bool)
the same odometry on /jackal_velocity_controller/odom, and the true pose on
/dynabarn/ground_truth. Subscribed: /cmd_vel and /jackal_velocity_controller/cmd_vel
(geometry_msgs/Twist).
Every name can be remapped with the usual `name:=other` arguments.

Lockstep (default): after publishing a control period's messages the node waits for the
first /cmd_vel that arrives after them (or the timeout) and answers with it; the simulation
does not advance meanwhile. Paced (`--paced`): it answers at once with the latest /cmd_vel.
"""

from __future__ import annotations

import argparse
import math
import struct
import sys
import threading
import time

HEADER = struct.Struct("<cI")
OBSERVATION = struct.Struct("<7d")
COMMAND = struct.Struct("<ddB")


def read_frame(stream) -> tuple[bytes, bytes] | None:
    head = stream.read(HEADER.size)
    if len(head) < HEADER.size:
        return None
    kind, size = HEADER.unpack(head)
    body = stream.read(size)
    return (kind, body) if len(body) == size else None


def write_frame(stream, kind: bytes, body: bytes) -> None:
    stream.write(HEADER.pack(kind, len(body)) + body)
    stream.flush()


# Over 80 lines on purpose: the node is one rospy process whose publishers, subscriber and
# frame loop share their state; rospy imports only exist inside it (Debian's Python).
def main(argv: list[str]) -> int:
    import rospy
    from geometry_msgs.msg import PoseStamped, TransformStamped, Twist
    from nav_msgs.msg import Odometry
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import Bool
    from tf2_msgs.msg import TFMessage

    parser = argparse.ArgumentParser()
    parser.add_argument("--paced", action="store_true")
    parser.add_argument("--timeout", type=float, default=10.0)
    parser.add_argument("--ready-timeout", type=float, default=30.0)
    parser.add_argument("--angle-min", type=float, required=True)
    parser.add_argument("--angle-max", type=float, required=True)
    parser.add_argument("--range-min", type=float, required=True)
    parser.add_argument("--range-max", type=float, required=True)
    parser.add_argument("--laser-x", type=float, required=True)
    parser.add_argument("--laser-z", type=float, required=True)
    args = parser.parse_args(rospy.myargv(argv)[1:])

    rospy.set_param("/use_sim_time", True)
    rospy.init_node("dynabarn_bridge", disable_signals=True)
    clock = rospy.Publisher("/clock", Clock, queue_size=10)
    scan_pub = rospy.Publisher("/front/scan", LaserScan, queue_size=10)
    odom_pub = rospy.Publisher("/odometry/filtered", Odometry, queue_size=10)
    tf_pub = rospy.Publisher("/tf", TFMessage, queue_size=10)
    tf_static = rospy.Publisher("/tf_static", TFMessage, queue_size=1, latch=True)
    goal_pub = rospy.Publisher("/move_base_simple/goal", PoseStamped, queue_size=1, latch=True)
    collision_pub = rospy.Publisher("/collision", Bool, queue_size=1, latch=True)
    truth_pub = rospy.Publisher("/dynabarn/ground_truth", Odometry, queue_size=10)
    wheel_odom_pub = rospy.Publisher("/jackal_velocity_controller/odom", Odometry, queue_size=10)

    answer = threading.Condition()
    state = {"cmd": (0.0, 0.0), "count": 0}

    def on_cmd(msg: Twist) -> None:
        with answer:
            state["cmd"] = (float(msg.linear.x), float(msg.angular.z))
            state["count"] += 1
            answer.notify_all()

    # The Jackal's twist_mux takes /cmd_vel; the challenge's move_base launch files publish
    # straight to the controller's input. Both drive the robot here.
    rospy.Subscriber("/cmd_vel", Twist, on_cmd, queue_size=10, tcp_nodelay=True)
    rospy.Subscriber("/jackal_velocity_controller/cmd_vel", Twist, on_cmd, queue_size=10, tcp_nodelay=True)

    def send_action_goal(goal) -> None:
        """Also give the goal through the `move_base` action, as the challenge's run.py does,
        when the stack offers that action server."""
        import actionlib
        from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal

        deadline = time.monotonic() + 1.0
        while "/move_base/status" not in dict(rospy.get_published_topics()):
            if time.monotonic() > deadline:
                return  # no move_base action server: the topic alone gives the goal
            time.sleep(0.05)
        client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
        if _wait(client):
            client.send_goal(MoveBaseGoal(target_pose=goal))
            state["action_client"] = client  # keep it (and its connections) alive

    def _wait(client) -> bool:
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:  # wall time: /clock does not run before the first tick
            if _server_connected(client):
                return True
            time.sleep(0.05)
        return False

    def _server_connected(client) -> bool:
        ac = client.action_client
        return ac.pub_goal.get_num_connections() > 0 and ac.status_sub.get_num_connections() > 0

    def stamp_of(t: float):
        return rospy.Time(int(t), round((t - int(t)) * 1e9) % 1_000_000_000)

    def transform(parent: str, child: str, t: float, x: float, y: float, z: float, yaw: float):
        tr = TransformStamped()
        tr.header.stamp = stamp_of(t)
        tr.header.frame_id = parent
        tr.child_frame_id = child
        tr.transform.translation.x, tr.transform.translation.y, tr.transform.translation.z = x, y, z
        tr.transform.rotation.z, tr.transform.rotation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        return tr

    tf_static.publish(TFMessage([transform("base_link", "front_laser", 0.0, args.laser_x, 0.0, args.laser_z, 0.0)]))
    inp, out = sys.stdin.buffer, sys.stdout.buffer
    while True:
        frame = read_frame(inp)
        if frame is None:
            break
        kind, body = frame
        if kind == b"G":
            x, y, yaw = struct.unpack("<3d", body)
            goal = PoseStamped()
            goal.header.frame_id = "odom"
            goal.pose.position.x, goal.pose.position.y = x, y
            goal.pose.orientation.z, goal.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            goal_pub.publish(goal)
            # Ready once a stack listens to the scan and publishes commands (or on timeout).
            deadline = time.monotonic() + args.ready_timeout
            while time.monotonic() < deadline and not (
                scan_pub.get_num_connections() > 0 and odom_pub.get_num_connections() > 0
            ):
                time.sleep(0.02)
            ready = scan_pub.get_num_connections() > 0
            time.sleep(0.2)  # let the stack's own subscriptions and its /cmd_vel publisher connect
            send_action_goal(goal)
            write_frame(out, b"R", COMMAND.pack(0.0, 0.0, 1 if ready else 0))
        elif kind == b"O":
            t, x, y, yaw, v, w, n = OBSERVATION.unpack_from(body)
            ranges = struct.unpack_from(f"<{int(n)}f", body, OBSERVATION.size)
            stamp = stamp_of(t)
            clock.publish(Clock(stamp))
            tf_pub.publish(TFMessage([transform("odom", "base_link", t, x, y, 0.0, yaw)]))
            odom = Odometry()
            odom.header.stamp, odom.header.frame_id, odom.child_frame_id = stamp, "odom", "base_link"
            odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
            odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            odom.twist.twist.linear.x, odom.twist.twist.angular.z = v, w
            odom_pub.publish(odom)
            wheel_odom_pub.publish(odom)  # the controller's odometry, which some stacks read
            truth_pub.publish(odom)
            scan = LaserScan()
            scan.header.stamp, scan.header.frame_id = stamp, "front_laser"
            scan.angle_min, scan.angle_max = args.angle_min, args.angle_max
            scan.angle_increment = (args.angle_max - args.angle_min) / max(int(n) - 1, 1)
            scan.range_min, scan.range_max = args.range_min, args.range_max
            scan.ranges = ranges
            with answer:
                seen = state["count"]
                scan_pub.publish(scan)  # last: a stack that acts on the scan has the odometry
                answered = True
                if not args.paced:
                    answered = answer.wait_for(lambda seen=seen: state["count"] > seen, timeout=args.timeout)
                cmd_v, cmd_w = state["cmd"]
            write_frame(out, b"C", COMMAND.pack(cmd_v, cmd_w, 1 if answered else 0))
        elif kind == b"E":
            collision_pub.publish(Bool(body.decode() == "collision"))
            time.sleep(0.1)
    rospy.signal_shutdown("simulation ended")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
