"""The ROS 2 side of `dynabarn-ros --ros 2`: `node.py`'s bridge node (the same frames from the
simulation, the same boot, lockstep, timer-driven and paced periods, the same topic names
and frames) over rclpy, for a ROS 2 navigation stack such as Nav2.

Runs on Debian's `/usr/bin/python3` with the ROS 2 prefix's environment (`ros2_build`), as
its own process, and imports nothing of dynabarn but `node.py` beside it. What differs
from ROS 1:

- no master: the planner gives the node and the stack a DDS domain of their own
  (`ROS_DOMAIN_ID`) and keeps discovery on this machine (`ROS_AUTOMATIC_DISCOVERY_RANGE=
  LOCALHOST`);
- QoS as Nav2 expects: the scan with the sensor-data profile (best effort), /tf_static, the
  goal and /robot_description transient-local (what ROS 1 latches), the rest reliable;
- the goal also as `/goal_pose` (Nav2's topic) and through Nav2's `navigate_to_pose`
  action once a stack offers it (where `nav2_msgs` is built);
- the robot's description (a URDF of the Jackal's base and laser) on /robot_description
  from the start, as `robot_state_publisher` gives it under Gazebo.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from pathlib import Path

# `node.py` beside this file, also in safe-path mode (PYTHONSAFEPATH, which the package sets
# for every Python it starts), where a script's own folder is not on sys.path.
sys.path.insert(0, str(Path(__file__).resolve().parent))
from node import ENDED, Node, _arguments, serve

URDF = """<?xml version="1.0"?>
<robot name="jackal">
  <link name="base_link"/>
  <link name="front_laser"/>
  <joint name="front_laser_mount" type="fixed">
    <parent link="base_link"/>
    <child link="front_laser"/>
    <origin xyz="{x} 0 {z}" rpy="0 0 0"/>
  </joint>
</robot>
"""


RECORDER_SETTLE = 0.5
"""[s] of wall time the boot goes on after the recorder has subscribed to every topic."""


class Ros2Node(Node):
    """`Node` over rclpy: its publishers and subscriptions with ROS 2's QoS, the rest inherited."""

    ACTION = "navigate_to_pose"

    def __init__(self, args, ros) -> None:
        from builtin_interfaces.msg import Time
        from geometry_msgs.msg import PoseStamped, Twist
        from nav_msgs.msg import Odometry
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import LaserScan
        from std_msgs.msg import Bool, String
        from tf2_msgs.msg import TFMessage

        self.ros, self.args, self.Time = ros, args, Time
        self.ticks_per_period = max(1, round(args.period / args.clock_step))
        self.Clock, self.Odometry, self.LaserScan, self.TFMessage = Clock, Odometry, LaserScan, TFMessage
        self.PoseStamped, self.Bool = PoseStamped, Bool
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.clock_pub = ros.create_publisher(Clock, "/clock", QoSProfile(depth=100))
        self.scan_pub = ros.create_publisher(LaserScan, "/front/scan", qos_profile_sensor_data)
        self.odom_pub = ros.create_publisher(Odometry, "/odometry/filtered", reliable)
        self.tf_pub = ros.create_publisher(TFMessage, "/tf", QoSProfile(depth=100))
        self.tf_static = ros.create_publisher(TFMessage, "/tf_static", latched)
        self.goal_pub = ros.create_publisher(PoseStamped, "/move_base_simple/goal", latched)
        self.nav2_goal_pub = ros.create_publisher(PoseStamped, "/goal_pose", latched)
        self.collision_pub = ros.create_publisher(Bool, "/collision", latched)
        self.truth_pub = ros.create_publisher(Odometry, "/dynabarn/ground_truth", reliable)
        self.wheel_odom_pub = ros.create_publisher(Odometry, "/jackal_velocity_controller/odom", reliable)
        self.description_pub = ros.create_publisher(String, "/robot_description", latched)
        self.answer = threading.Condition()
        self.cmd, self.count = (0.0, 0.0), 0
        self.clock_now = 0.0
        self.heard_at: float | None = None
        self.firing: float | None = None
        self._clock_lock = threading.Lock()
        self._ticker: threading.Thread | None = None
        self._stop_ticks = threading.Event()
        self.action_client = None
        self._no_action = False
        self._client = None  # the navigate_to_pose client, made once nav2_msgs imports
        self._sent = None  # the last goal's acceptance, on its way
        self._next_try = 0.0  # [monotonic s] when a rejected goal is offered again
        self._recorder_seen: tuple[float, int] | None = None  # when (and at which command) it had subscribed
        self._navigation = None  # the accepted navigation's result, on its way
        # The Jackal's twist_mux takes /cmd_vel; the challenge's launch files publish straight
        # to the controller's input. Both drive the robot here.
        ros.create_subscription(Twist, "/cmd_vel", self._on_cmd, reliable)
        ros.create_subscription(Twist, "/jackal_velocity_controller/cmd_vel", self._on_cmd, reliable)
        self.description_pub.publish(String(data=URDF.format(x=args.laser_x, z=args.laser_z)))
        static = self._transform("base_link", "front_laser", 0.0, args.laser_x, 0.0, args.laser_z, 0.0)
        self.tf_static.publish(TFMessage(transforms=[static]))

    def subscribers(self, publisher) -> int:
        """Subscriptions to `publisher`'s topic, a recorder's (`--recorder`) not counted: it is not the stack."""
        if not self.args.recorder:
            return publisher.get_subscription_count()
        found = self.ros.get_subscriptions_info_by_topic(publisher.topic_name)
        return sum(info.node_name != self.args.recorder for info in found)

    def not_ready(self) -> str:
        """The recorder (`--recorder`: `ros2 bag record`) must have subscribed to every topic
        the bridge publishes, and to each it takes that the stack publishes (/cmd_vel),
        before the episode starts: the bag holds it whole."""
        if not self.args.recorder:
            return ""
        topics = {publisher.topic_name for publisher in self.ros.publishers}
        topics |= {s.topic_name for s in self.ros.subscriptions if self.ros.count_publishers(s.topic_name) > 0}
        missing = sorted(
            topic
            for topic in topics
            if not topic.startswith("/rosout")
            and not topic.endswith("parameter_events")
            and all(info.node_name != self.args.recorder for info in self.ros.get_subscriptions_info_by_topic(topic))
        )
        if missing:
            return f"the recorder {self.args.recorder} never subscribed to {', '.join(missing)}"
        # Seen subscribed here is not yet matched with the stack's publisher (DDS matches each
        # pair on its own): the stack's first commands after it went unrecorded. The boot
        # goes on for RECORDER_SETTLE s and, where the stack commands while booting, two more
        # commands (a command per boot period).
        with self.answer:
            count = self.count
        if self._recorder_seen is None:
            self._recorder_seen = (time.monotonic(), count)
        since, at = self._recorder_seen
        commands = count >= at + 2 or self.args.ready == "subscribed"
        if time.monotonic() - since < RECORDER_SETTLE or not commands:
            return f"the recorder {self.args.recorder} subscribed, but the stack's commands did not reach it yet"
        return ""

    def _stamp(self, t: float):
        return self.Time(sec=int(t), nanosec=round((t - int(t)) * 1e9) % 1_000_000_000)

    def boot(self, obs, ranges, goal):
        msg = self.PoseStamped()
        msg.header.frame_id = "odom"
        msg.pose.position.x, msg.pose.position.y = goal[0], goal[1]
        msg.pose.orientation.z, msg.pose.orientation.w = math.sin(goal[2] / 2), math.cos(goal[2] / 2)
        self.nav2_goal_pub.publish(msg)  # Nav2's goal topic, latched; the rest as on ROS 1
        return super().boot(obs, ranges, goal)

    def _offer_action_goal(self, goal) -> None:
        """The goal through Nav2's `navigate_to_pose` action too, once a stack offers it
        (where nav2_msgs is built; otherwise the topics alone), sent again until the server
        accepts it: Nav2's lifecycle nodes offer the action from their configuration on but
        reject every goal (silently) until they are active."""
        if self._no_action or self.action_client is not None:
            return
        try:
            from nav2_msgs.action import NavigateToPose
            from rclpy.action import ActionClient
        except ImportError:
            self._no_action = True
            return
        self._client = self._client or ActionClient(self.ros, NavigateToPose, self.ACTION)
        if self._sent is not None and not self._sent.done():
            return  # the server's answer is on its way
        if self._navigation_result() is not None:
            return  # taken: the stack navigates
        if self._client.server_is_ready() and time.monotonic() >= self._next_try:
            self._next_try = time.monotonic() + 0.25  # a rejected goal is offered again, 4 times a second
            self._sent = self._client.send_goal_async(NavigateToPose.Goal(pose=goal))

    def _navigation_result(self):
        """The future of the navigation's result once the stack accepted the goal, else None.
        Read here as well as in the boot: the boot ends on the stack's first command, which
        may come before the acceptance is read."""
        sent = self._sent
        accepted = sent is not None and sent.done() and sent.result() is not None and sent.result().accepted
        if self._navigation is None and accepted:
            self.action_client = self._client
            self._navigation = sent.result().get_result_async()
        return self._navigation

    def period(self, t: float, obs: tuple, ranges) -> tuple[float, float, int]:
        """As `Node.period`, until the stack's `navigate_to_pose` ends (Nav2 gives up after
        its recoveries, or thinks the goal reached): from then on the robot stands, as under
        Gazebo after move_base aborts, and each period runs at once (answered `ENDED`)."""
        navigation = self._navigation_result()
        if navigation is None or not navigation.done() or self.args.paced:
            return super().period(t, obs, ranges)
        self.publish_state(t, obs, ranges)
        for tick in self.ticks_after(t):
            self.tick(tick)
        return 0.0, 0.0, ENDED


def main(argv: list[str]) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    # ROS 1's `from:=to` arguments (what the planner passes for --remap) as ROS 2's remappings.
    remaps = [a for a in argv[1:] if ":=" in a]
    rclpy.init(args=[argv[0], "--ros-args", *(x for r in remaps for x in ("-r", r))] if remaps else argv[:1])
    args = _arguments([a for a in argv[1:] if ":=" not in a])
    ros = rclpy.create_node("dynabarn_bridge")
    node = Ros2Node(args, ros)
    executor = SingleThreadedExecutor()
    executor.add_node(ros)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        serve(node, sys.stdin.buffer, sys.stdout.buffer)
    finally:
        executor.shutdown(timeout_sec=1.0)
        ros.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
