"""The ROS side of `dynabarn-ros`: a rospy node that makes the simulation look like the BARN
Challenge's Gazebo to a ROS 1 navigation stack.

Runs on Debian's `/usr/bin/python3` (where Debian's rospy lives), as its own process, and
imports nothing of dynabarn: the simulation (the project's Python, with MuJoCo) talks to it
over stdin/stdout in length-prefixed frames (struct-packed, little endian):

    sim -> node  'B' boot: the spawn's observation (as 'O') and the goal x, y, yaw (odom)
                 'O' observation: t, x, y, yaw (odom), v, w, X, Y, YAW (world), n, ranges[n]
                 'E' end: outcome text (published on /collision when it is a collision)
    node -> sim  'R' ready: t0 (the stamp of episode time 0), ready (0/1), what was missing
                 'C' command: v, w, answered (1 answered, 0 held: the last command again,
                 2 the stack's navigation has ended: it stands, with nothing to wait for)

Boot (like Gazebo, which publishes from the moment it starts): from the 'B' frame on, a
thread publishes a running /clock at real time in steps of `--clock-step` (from one step
on, never 0), and with it /tf, odometry and scans of the robot standing at its spawn, and
the goal (latched, and through the `move_base` action once a server offers it), until the
stack is ready: `--ready subscribed` (something subscribed to the scan) or `--ready
command` (it sent a /cmd_vel after the goal: started, planned and controlling; default).
The episode's stamps then continue the clock from `t0`, the next whole control period.

Every control period: /clock at the period's start, /tf (odom -> base_link), odometry
(/odometry/filtered and /jackal_velocity_controller/odom), the true pose in the world frame
(/dynabarn/ground_truth), the scan last (/front/scan, frame front_laser), then /clock on
through the period in `--clock-step`s, so a stack's timers on ROS time fire at their
rates. Lockstep (default): at once, then the answer is the first /cmd_vel (or
/jackal_velocity_controller/cmd_vel) published after the scan, waited for up to `--grace`
wall seconds; without one the last command holds for the period (answered 0), and after
`--timeout` wall seconds without any command the simulation ends the episode. With
`--stack-rate HZ` (a stack whose loop runs from a timer, as move_base's controller does),
the clock stands still at each tick where that timer fires until the loop's command
comes, so the loop runs at its rate in simulated time; the period's answer is the last
of them. Paced
(`--paced`): the ticks are spread over the period at the simulation's rate and the answer
is the latest command at once. Every name can be remapped with `name:=other` arguments.
"""

from __future__ import annotations

import argparse
import math
import struct
import sys
import threading
import time

HEADER = struct.Struct("<cI")
OBSERVATION = struct.Struct("<10d")
GOAL = struct.Struct("<3d")
COMMAND = struct.Struct("<ddB")
READY = struct.Struct("<dB")
ENDED = 2
"""'C' answered: the stack's navigation action ended (aborted or done), so no command will come."""
PROBE = 0.1
"""Wall seconds each tick is held while a timer-driven stack's phase is still unknown."""


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


def _arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    parser.add_argument("--paced", action="store_true")
    parser.add_argument("--rate", type=float, default=1.0)
    parser.add_argument("--timeout", type=float, default=10.0)
    parser.add_argument("--grace", type=float, default=0.5)
    parser.add_argument("--ready", choices=["subscribed", "command"], default="command")
    parser.add_argument("--ready-timeout", type=float, default=30.0)
    parser.add_argument("--recorder", default="")  # a recorder node the boot waits for (ROS 2's)
    parser.add_argument("--clock-step", type=float, default=0.005)
    parser.add_argument("--stack-rate", type=float, default=0.0)
    parser.add_argument("--period", type=float, default=0.1)
    parser.add_argument("--angle-min", type=float, required=True)
    parser.add_argument("--angle-max", type=float, required=True)
    parser.add_argument("--range-min", type=float, required=True)
    parser.add_argument("--range-max", type=float, required=True)
    parser.add_argument("--laser-x", type=float, required=True)
    parser.add_argument("--laser-z", type=float, required=True)
    return parser.parse_args(argv)


class Node:
    """The bridge node's publishers, subscriptions and clock (see the module docstring)."""

    ACTION = "move_base"
    """The navigation action the goal is also sent through, once a stack offers its server."""

    def __init__(self, args: argparse.Namespace) -> None:
        import rospy
        from geometry_msgs.msg import PoseStamped, Twist
        from nav_msgs.msg import Odometry
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import LaserScan
        from std_msgs.msg import Bool
        from tf2_msgs.msg import TFMessage

        self.rospy, self.args = rospy, args
        self.ticks_per_period = max(1, round(args.period / args.clock_step))
        self.Clock, self.Odometry, self.LaserScan, self.TFMessage = Clock, Odometry, LaserScan, TFMessage
        self.PoseStamped, self.Bool = PoseStamped, Bool
        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=100)
        self.scan_pub = rospy.Publisher("/front/scan", LaserScan, queue_size=10)
        self.odom_pub = rospy.Publisher("/odometry/filtered", Odometry, queue_size=10)
        self.tf_pub = rospy.Publisher("/tf", TFMessage, queue_size=10)
        self.tf_static = rospy.Publisher("/tf_static", TFMessage, queue_size=1, latch=True)
        self.goal_pub = rospy.Publisher("/move_base_simple/goal", PoseStamped, queue_size=1, latch=True)
        self.collision_pub = rospy.Publisher("/collision", Bool, queue_size=1, latch=True)
        self.truth_pub = rospy.Publisher("/dynabarn/ground_truth", Odometry, queue_size=10)
        self.wheel_odom_pub = rospy.Publisher("/jackal_velocity_controller/odom", Odometry, queue_size=10)
        self.answer = threading.Condition()
        self.cmd, self.count = (0.0, 0.0), 0
        self.clock_now = 0.0
        self.heard_at: float | None = None
        """The clock when the last command came (while the clock stood still: the tick that
        fired the stack's timer)."""
        self.firing: float | None = None
        """A tick at which the stack's timer fired (its phase), when `--stack-rate` is known."""
        self._clock_lock = threading.Lock()
        self._ticker: threading.Thread | None = None
        self._stop_ticks = threading.Event()
        self.action_client = None
        # The Jackal's twist_mux takes /cmd_vel; the challenge's move_base launch files publish
        # straight to the controller's input. Both drive the robot here.
        rospy.Subscriber("/cmd_vel", Twist, self._on_cmd, queue_size=10, tcp_nodelay=True)
        rospy.Subscriber("/jackal_velocity_controller/cmd_vel", Twist, self._on_cmd, queue_size=10, tcp_nodelay=True)
        static = self._transform("base_link", "front_laser", 0.0, args.laser_x, 0.0, args.laser_z, 0.0)
        self.tf_static.publish(TFMessage(transforms=[static]))

    def _on_cmd(self, msg) -> None:
        with self.answer:
            self.cmd = (float(msg.linear.x), float(msg.angular.z))
            self.count += 1
            self.heard_at = self.clock_now
            self.answer.notify_all()

    # -- what differs between ROS 1 and ROS 2 (node2.Ros2Node overrides these) ---------------
    def subscribers(self, publisher) -> int:
        """How many subscribers `publisher` has."""
        return publisher.get_num_connections()

    def end(self, outcome: str) -> None:
        """The episode ended: /collision says whether in a collision."""
        self._stop_ticks.set()
        self.collision_pub.publish(self.Bool(data=outcome == "collision"))

    # -- messages ---------------------------------------------------------------------------
    def _stamp(self, t: float):
        return self.rospy.Time(int(t), round((t - int(t)) * 1e9) % 1_000_000_000)

    def _transform(self, parent: str, child: str, t: float, x: float, y: float, z: float, yaw: float):
        from geometry_msgs.msg import TransformStamped

        tr = TransformStamped()
        tr.header.stamp = self._stamp(t)
        tr.header.frame_id, tr.child_frame_id = parent, child
        tr.transform.translation.x, tr.transform.translation.y, tr.transform.translation.z = x, y, z
        tr.transform.rotation.z, tr.transform.rotation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        return tr

    def _odometry(self, t: float, frame: str, x: float, y: float, yaw: float, v: float, w: float):
        odom = self.Odometry()
        odom.header.stamp, odom.header.frame_id, odom.child_frame_id = self._stamp(t), frame, "base_link"
        odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
        odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        odom.twist.twist.linear.x, odom.twist.twist.angular.z = v, w
        return odom

    def tick(self, t: float) -> None:
        """/clock at t (never backwards)."""
        with self._clock_lock:
            if t > self.clock_now:
                self.clock_now = t
                self.clock_pub.publish(self.Clock(clock=self._stamp(t)))

    def publish_state(self, t: float, obs: tuple, ranges) -> None:
        """The clock at t, then the robot's transform, odometry, true pose and (last) scan."""
        _, x, y, yaw, v, w, wx, wy, wyaw, _ = obs
        self.tick(t)
        self.tf_pub.publish(self.TFMessage(transforms=[self._transform("odom", "base_link", t, x, y, 0.0, yaw)]))
        odom = self._odometry(t, "odom", x, y, yaw, v, w)
        self.odom_pub.publish(odom)
        self.wheel_odom_pub.publish(odom)  # the controller's odometry, which some stacks read
        self.truth_pub.publish(self._odometry(t, "world", wx, wy, wyaw, v, w))
        a = self.args
        scan = self.LaserScan()
        scan.header.stamp, scan.header.frame_id = self._stamp(t), "front_laser"
        scan.angle_min, scan.angle_max = a.angle_min, a.angle_max
        scan.angle_increment = (a.angle_max - a.angle_min) / max(len(ranges) - 1, 1)
        scan.range_min, scan.range_max = a.range_min, a.range_max
        scan.ranges = ranges
        self.scan_pub.publish(scan)

    # -- boot -------------------------------------------------------------------------------
    def boot(self, obs: tuple, ranges, goal: tuple[float, float, float]) -> tuple[float, bool, str]:
        """Publish the spawn on a running clock until the stack is ready (or the timeout):
        (t0, ready, what was missing)."""
        a = self.args
        msg = self.PoseStamped()
        msg.header.frame_id = "odom"
        msg.pose.position.x, msg.pose.position.y = goal[0], goal[1]
        msg.pose.orientation.z, msg.pose.orientation.w = math.sin(goal[2] / 2), math.cos(goal[2] / 2)
        stop = threading.Event()
        every = self.ticks_per_period

        def run() -> None:  # real time from one clock step on: the stack's timers and tf waits run
            k, wall0 = 0, time.monotonic()
            while not stop.is_set():
                k += 1
                t = k * a.clock_step
                if k % every == 0:
                    self.publish_state(t, obs, ranges)
                else:
                    self.tick(t)
                time.sleep(max(0.0, wall0 + t - time.monotonic()))

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        with self.answer:
            seen = self.count
        self.goal_pub.publish(msg)
        deadline = time.monotonic() + a.ready_timeout
        ready = False
        waiting = ""
        while time.monotonic() < deadline and not ready:
            time.sleep(0.02)
            subscribed = self.subscribers(self.scan_pub) > 0
            if subscribed and self.action_client is None:
                self._offer_action_goal(msg)
            with self.answer:
                commanded = self.count > seen
            ready = subscribed if a.ready == "subscribed" else commanded
            waiting = self.not_ready() if ready else ""
            ready = ready and not waiting
        stop.set()
        thread.join()
        missing = ""
        if waiting:
            missing = waiting
        elif not ready:
            if self.subscribers(self.scan_pub) == 0:
                missing = "nothing subscribed to the scan"
            else:
                missing = "a node subscribed to the scan, but no /cmd_vel came"
                if self.action_client is None:
                    missing += f" (and no {self.ACTION} action server took the goal)"
        # The episode starts at the next whole control period after the boot's clock.
        t0 = (math.floor(self.clock_now / a.period + 1e-9) + 1) * a.period
        return t0, ready, missing

    def not_ready(self) -> str:
        """What else the boot waits for once the stack is ready ("" for nothing)."""
        return ""

    def _offer_action_goal(self, goal) -> None:
        """The goal through the `move_base` action too, as the challenge's run.py gives it,
        once a stack offers that action server."""
        if "/move_base/status" not in dict(self.rospy.get_published_topics()):
            return
        import actionlib
        from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal

        client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
        ac = client.action_client
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            if ac.pub_goal.get_num_connections() > 0 and ac.status_sub.get_num_connections() > 0:
                client.send_goal(MoveBaseGoal(target_pose=goal))
                self.action_client = client  # keep it (and its connections) alive
                return
            time.sleep(0.05)

    # -- control periods --------------------------------------------------------------------
    def period(self, t: float, obs: tuple, ranges) -> tuple[float, float, int]:
        """One control period from stamp t: (v, w, answered)."""
        a = self.args
        self._stop_ticks.set()
        if self._ticker is not None:
            self._ticker.join()
        with self.answer:
            seen = self.count
        self.publish_state(t, obs, ranges)
        ticks = self.ticks_after(t)
        if a.paced:  # the ticks at the simulation's pace, while it runs the period
            self._stop_ticks = threading.Event()
            self._ticker = threading.Thread(target=self._paced_ticks, args=(ticks, self._stop_ticks), daemon=True)
            self._ticker.start()
            with self.answer:
                return (*self.cmd, 1)
        if a.stack_rate <= 0:  # a stack that answers the scan: the period's ticks, then its answer
            for tick in ticks:
                self.tick(tick)
            with self.answer:
                answered = self.answer.wait_for(lambda: self.count > seen, timeout=a.grace)
                return (*self.cmd, 1 if answered else 0)
        return self._timed_period(t, ticks, seen)

    def ticks_after(self, t: float) -> list[float]:
        """The /clock stamps of the control period from t, after its first."""
        return [t + k * self.args.clock_step for k in range(1, self.ticks_per_period)]

    def _timed_period(self, t: float, ticks: list[float], seen: int) -> tuple[float, float, int]:
        """A stack whose loop runs from a timer at `--stack-rate`: the clock stands still at
        each tick where the timer fires until the loop's /cmd_vel comes (or the grace ends),
        so the loop computes in no simulated time and runs at its rate, as in Gazebo. The
        timer's phase is found once: tick by tick, each held until a command comes or
        `PROBE` wall seconds pass."""
        a = self.args
        every = 1.0 / a.stack_rate
        answered = False
        for tick in [t, *ticks]:
            self.tick(tick)
            if self.firing is None:
                wait = PROBE
            elif abs((tick - self.firing) / every - round((tick - self.firing) / every)) * every < a.clock_step / 2:
                wait = a.grace
            else:
                continue
            with self.answer:
                before = self.count
                if self.answer.wait_for(lambda before=before: self.count > before, timeout=wait):
                    answered = True
                    self.firing = self.heard_at  # the clock stood at this tick
        with self.answer:
            return (*self.cmd, 1 if answered or self.count > seen else 0)

    def _paced_ticks(self, ticks: list[float], stop: threading.Event) -> None:
        wall0 = time.monotonic()
        for k, tick in enumerate(ticks, start=1):
            if stop.wait(max(0.0, wall0 + k * self.args.clock_step / self.args.rate - time.monotonic())):
                return
            self.tick(tick)


def serve(node: Node, inp, out) -> None:
    """The frames from the simulation, answered, until its pipe closes (see the module docstring)."""
    t0 = 0.0
    while True:
        frame = read_frame(inp)
        if frame is None:
            break
        kind, body = frame
        if kind in (b"B", b"O"):
            obs = OBSERVATION.unpack_from(body)
            ranges = struct.unpack_from(f"<{int(obs[-1])}f", body, OBSERVATION.size)
            if kind == b"B":
                goal = GOAL.unpack_from(body, OBSERVATION.size + 4 * len(ranges))
                t0, ready, missing = node.boot(obs, ranges, goal)
                write_frame(out, b"R", READY.pack(t0, 1 if ready else 0) + missing.encode())
            else:
                write_frame(out, b"C", COMMAND.pack(*node.period(t0 + obs[0], obs, ranges)))
        elif kind == b"E":
            node.end(body.decode())
            time.sleep(0.1)


def main(argv: list[str]) -> int:
    import rospy

    args = _arguments(rospy.myargv(argv)[1:])
    rospy.set_param("/use_sim_time", True)
    rospy.init_node("dynabarn_bridge", disable_signals=True)
    serve(Node(args), sys.stdin.buffer, sys.stdout.buffer)
    rospy.signal_shutdown("simulation ended")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
