"""Recordings as ROS bags, for `rosbag`, `rostopic`, rviz and ROS 2 tools: ROS message types
written with `rosbags` (pure Python; the `ros` extra), read back by ROS's own tools.

| topic | type | from the recording |
|---|---|---|
| /front/scan | sensor_msgs/LaserScan (frame front_laser) | /scan |
| /odometry/filtered | nav_msgs/Odometry (world -> base_link; twist: measured v, w) | /robot/pose, /metrics |
| /tf | tf2_msgs/TFMessage (world -> base_link) | /robot/pose |
| /tf_static | tf2_msgs/TFMessage (base_link -> front_laser), once | metadata |
| /cmd_vel | geometry_msgs/Twist (the command the robot received) | /cmd_vel |
| /obstacles | visualization_msgs/MarkerArray (one marker per obstacle) | /world/obstacles |
| /dynabarn/metadata, /dynabarn/result | std_msgs/String (JSON) | /world/metadata, /episode/result |

ROS 1 bags use the Noetic message definitions; ROS 2 bags (version 9, MCAP storage, CDR)
use Humble's. Message times are the simulated times of the recording (log time = stamp).
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.files import fsync_folder
from dynabarn.recording import (
    CMD,
    METRICS,
    POSE,
    SCAN,
    Recording,
    obstacle_track,
    recorded_world,
)

FORMATS = ("rosbag1", "rosbag2")
_TF_MESSAGE = "geometry_msgs/TransformStamped[] transforms\n"


def _typestore(fmt: str):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if fmt == "rosbag1" else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in store.types:  # Noetic's store lacks it: its one-line definition
        store.register(get_types_from_msg(_TF_MESSAGE, "tf2_msgs/msg/TFMessage"))
    return store


# Over 80 lines on purpose: one pass from the recording's topics to the bag's, topic by
# topic in the table's order, sharing the message classes and the writer.
def export_bag(rec: Recording, out: Path, fmt: str) -> dict[str, int]:
    """Write the recording as a ROS bag at `out` (a .bag file, or a rosbag2 folder); returns
    the number of messages per topic. Written beside `out` and renamed when complete."""
    try:
        from rosbags.rosbag1 import Writer as Writer1
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2
    except ImportError:
        raise DynabarnError("exporting bags needs rosbags: pip install 'dynabarn[ros]'") from None
    if fmt not in FORMATS:
        raise DynabarnError(f"unknown format {fmt!r}; available: {', '.join(FORMATS)}")
    meta = rec.metadata
    if not meta:
        raise DynabarnError("the recording has no /world/metadata; not a dynabarn recording")
    out = Path(out)
    if out.exists():
        raise DynabarnError(f"{out} exists; choose another --out or remove it")
    store = _typestore(fmt)
    t = store.types
    Header, Time, Duration = (
        t[f"{n}"] for n in ("std_msgs/msg/Header", "builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration")
    )
    Vector3, Quaternion, Point = (t[f"geometry_msgs/msg/{n}"] for n in ("Vector3", "Quaternion", "Point"))
    Pose, Twist, Transform = (t[f"geometry_msgs/msg/{n}"] for n in ("Pose", "Twist", "Transform"))
    TransformStamped, PoseWithCovariance, TwistWithCovariance = (
        t[f"geometry_msgs/msg/{n}"] for n in ("TransformStamped", "PoseWithCovariance", "TwistWithCovariance")
    )
    TFMessage, LaserScan, String = t["tf2_msgs/msg/TFMessage"], t["sensor_msgs/msg/LaserScan"], t["std_msgs/msg/String"]
    Odometry, ColorRGBA = t["nav_msgs/msg/Odometry"], t["std_msgs/msg/ColorRGBA"]
    Marker, MarkerArray = t["visualization_msgs/msg/Marker"], t["visualization_msgs/msg/MarkerArray"]

    def header(time_s: float, frame: str, seq: int = 0):
        ns = round(time_s * 1e9)
        stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        return Header(seq=seq, stamp=stamp, frame_id=frame) if fmt == "rosbag1" else Header(stamp=stamp, frame_id=frame)

    def quat(yaw: float):
        return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def serialize(msg, msgtype: str) -> bytes:
        return store.serialize_ros1(msg, msgtype) if fmt == "rosbag1" else store.serialize_cdr(msg, msgtype)

    robot = meta.get("robot", {})
    laser_x = float(robot.get("laser_offset", [0.12, 0.0])[0])
    laser_z = float(robot.get("laser_z", 0.3))
    measured = {round(tm * 1e3): m for tm, m in rec.topic(METRICS.name)}
    world = recorded_world(rec)
    ot, oxy = obstacle_track(rec, world)
    zero6 = np.zeros(36)

    def ros2_marker_fields(ts: float) -> dict:
        """Humble's Marker has texture and mesh-file fields that Noetic's has not."""
        if "texture_resource" not in Marker.__dataclass_fields__:
            return {}
        image = t["sensor_msgs/msg/CompressedImage"](header=header(ts, ""), format="", data=np.zeros(0, np.uint8))
        mesh = t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8))
        return {"texture_resource": "", "texture": image, "uv_coordinates": [], "mesh_file": mesh}

    counts: dict[str, int] = {}
    # Written in a hidden staging folder (a rosbag2 bag names its file after its folder), then
    # renamed into place: a bag at `out` is always complete.
    staging = out.with_name(f".{out.name}.part")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    part = staging / out.name
    writer = Writer1(part) if fmt == "rosbag1" else Writer2(part, version=9, storage_plugin=StoragePlugin.MCAP)
    with writer:
        conns = {}

        def write(topic: str, msgtype: str, time_s: float, msg) -> None:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(conns[topic], round(time_s * 1e9), serialize(msg, msgtype))
            counts[topic] = counts.get(topic, 0) + 1

        write("/dynabarn/metadata", "std_msgs/msg/String", 0.0, String(data=json.dumps(meta, sort_keys=True)))
        static = TransformStamped(
            header=header(0.0, "base_link"),
            child_frame_id="front_laser",
            transform=Transform(translation=Vector3(x=laser_x, y=0.0, z=laser_z), rotation=quat(0.0)),
        )
        write("/tf_static", "tf2_msgs/msg/TFMessage", 0.0, TFMessage(transforms=[static]))
        for k, (ts, m) in enumerate(rec.topic(SCAN.name)):
            ranges = np.asarray(m.ranges, dtype=np.float32)
            scan = LaserScan(
                header=header(ts, "front_laser", k),
                angle_min=m.start_angle,
                angle_max=m.end_angle,
                angle_increment=(m.end_angle - m.start_angle) / max(len(ranges) - 1, 1),
                time_increment=0.0,
                scan_time=0.1,
                range_min=float(robot.get("laser_range", [0.1, 30.0])[0]),
                range_max=float(robot.get("laser_range", [0.1, 30.0])[1]),
                ranges=ranges,
                intensities=np.zeros(0, dtype=np.float32),
            )
            write("/front/scan", "sensor_msgs/msg/LaserScan", ts, scan)
        for k, (ts, m) in enumerate(rec.topic(POSE.name)):
            p, q = m.pose.position, m.pose.orientation
            yaw = 2.0 * math.atan2(q.z, q.w)
            tick = measured.get(round(ts * 1e3), {})
            pose = Pose(position=Point(x=p.x, y=p.y, z=0.0), orientation=quat(yaw))
            odom = Odometry(
                header=header(ts, "world", k),
                child_frame_id="base_link",
                pose=PoseWithCovariance(pose=pose, covariance=zero6),
                twist=TwistWithCovariance(
                    twist=Twist(
                        linear=Vector3(x=float(tick.get("v") or 0.0), y=0.0, z=0.0),
                        angular=Vector3(x=0.0, y=0.0, z=float(tick.get("w") or 0.0)),
                    ),
                    covariance=zero6,
                ),
            )
            write("/odometry/filtered", "nav_msgs/msg/Odometry", ts, odom)
            tf = TransformStamped(
                header=header(ts, "world", k),
                child_frame_id="base_link",
                transform=Transform(translation=Vector3(x=p.x, y=p.y, z=0.0), rotation=quat(yaw)),
            )
            write("/tf", "tf2_msgs/msg/TFMessage", ts, TFMessage(transforms=[tf]))
        for ts, m in rec.topic(CMD.name):
            cmd = Twist(linear=Vector3(x=float(m["v"]), y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=float(m["w"])))
            write("/cmd_vel", "geometry_msgs/msg/Twist", ts, cmd)
        red = ColorRGBA(r=0.85, g=0.15, b=0.12, a=1.0)
        for ts, xy in zip(ot.tolist(), oxy, strict=True):
            markers = []
            for i, o in enumerate(world.obstacles):
                q = quat(o.yaw)
                size = 2 * o.radius + 2 * o.half_length, 2 * o.radius + 2 * (o.half_width or 0.0)
                markers.append(
                    Marker(
                        header=header(ts, "world"),
                        ns="obstacles",
                        id=i,
                        type=1 if o.shape == "box" else 3,  # CUBE or CYLINDER
                        action=0,
                        pose=Pose(
                            position=Point(x=float(xy[i, 0]), y=float(xy[i, 1]), z=o.height / 2),
                            orientation=quat(o.yaw),
                        ),
                        scale=Vector3(x=size[0], y=size[1] if o.shape == "box" else size[0], z=o.height),
                        color=red,
                        lifetime=Duration(sec=0, nanosec=0),
                        frame_locked=False,
                        points=[],
                        colors=[],
                        text=o.name,
                        mesh_resource="",
                        mesh_use_embedded_materials=False,
                        **ros2_marker_fields(ts),
                    )
                )
            write("/obstacles", "visualization_msgs/msg/MarkerArray", ts, MarkerArray(markers=markers))
        if rec.result:
            end = float(rec.result.get("sim_time") or 0.0)
            write("/dynabarn/result", "std_msgs/msg/String", end, String(data=json.dumps(rec.result, sort_keys=True)))
    part.rename(out)
    staging.rmdir()
    fsync_folder(out.parent)
    return counts
