"""Our protobuf encoders against foxglove-sdk's own messages, decoded with its schemas."""

import math

import numpy as np
from foxglove.messages import (
    Color,
    CubePrimitive,
    CylinderPrimitive,
    LaserScan,
    Pose,
    PoseInFrame,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    Timestamp,
    Vector3,
)
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory

from dynabarn.recording import wire

FRAME = wire.string(2, "world")


_DECODERS = {}


def _decode(message_type, data: bytes):
    """Decode with the SDK's schema, re-serialised canonically so messages compare by value."""
    if message_type not in _DECODERS:
        s = message_type.get_schema()
        schema = Schema(id=1, name=s.name, encoding=s.encoding, data=s.data)
        _DECODERS[message_type] = DecoderFactory().decoder_for("protobuf", schema)
    msg = _DECODERS[message_type](data)
    return msg.SerializeToString(deterministic=True), msg


def _pose(x, y, z, yaw):
    return Pose(
        position=Vector3(x=x, y=y, z=z), orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
    )


def test_varint():
    assert wire.varint(0) == b"\x00" and wire.varint(1) == b"\x01" and wire.varint(300) == b"\xac\x02"
    assert wire.varint(2**35 + 5) == wire._varint_slow(2**35 + 5)


def test_pose_in_frame_matches_sdk():
    for ns, yaw in ((0, 0.0), (1_500_000_000, 2.0), (123_456_789_012, -3.0)):
        ours = wire.pose_in_frame(ns, FRAME, wire.pose(1.5, -2.25, 0.0, 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))
        sdk = PoseInFrame(
            timestamp=Timestamp(sec=ns // 10**9, nsec=ns % 10**9), frame_id="world", pose=_pose(1.5, -2.25, 0.0, yaw)
        ).encode()
        assert _decode(PoseInFrame, ours)[0] == _decode(PoseInFrame, sdk)[0]


def test_laser_scan_matches_sdk():
    ranges = np.random.default_rng(0).uniform(0.1, 30.0, 720)
    pose_body = wire.pose(3.0, 1.0, 0.3, 0.0, 0.0, math.sin(0.5), math.cos(0.5))
    ours = wire.laser_scan(2_000_000_000, FRAME, pose_body, -2.35619, 2.35619, ranges)
    sdk = LaserScan(
        timestamp=Timestamp(sec=2, nsec=0),
        frame_id="world",
        pose=_pose(3.0, 1.0, 0.3, 1.0),
        start_angle=-2.35619,
        end_angle=2.35619,
        ranges=ranges.tolist(),
        intensities=[],
    ).encode()
    (a, msg), (b, _) = _decode(LaserScan, ours), _decode(LaserScan, sdk)
    assert a == b and list(msg.ranges) == ranges.tolist()


def test_scene_update_matches_sdk():
    ident = (0.0, 0.0, 0.0, 1.0)
    cyl = wire.cylinder(
        wire.pose(1.0, 2.0, 0.5, *ident), wire.vector3(1.0, 1.0, 1.0), wire.color(0.85, 0.15, 0.12, 1.0)
    )
    cube = wire.cube(wire.pose(-10.0, 0.0, 0.5, *ident), wire.vector3(0.5, 20.0, 1.0), wire.color(0.5, 0.5, 0.5, 1.0))
    ours = wire.scene_update([wire.scene_entity(100_000_000, FRAME, "obstacles", cylinders=[cyl], cubes=[cube])])
    sdk = SceneUpdate(
        entities=[
            SceneEntity(
                timestamp=Timestamp(sec=0, nsec=100_000_000),
                frame_id="world",
                id="obstacles",
                cylinders=[
                    CylinderPrimitive(
                        pose=_pose(1.0, 2.0, 0.5, 0.0),
                        size=Vector3(x=1.0, y=1.0, z=1.0),
                        bottom_scale=1.0,
                        top_scale=1.0,
                        color=Color(r=0.85, g=0.15, b=0.12, a=1.0),
                    )
                ],
                cubes=[
                    CubePrimitive(
                        pose=_pose(-10.0, 0.0, 0.5, 0.0),
                        size=Vector3(x=0.5, y=20.0, z=1.0),
                        color=Color(r=0.5, g=0.5, b=0.5, a=1.0),
                    )
                ],
            )
        ]
    ).encode()
    assert _decode(SceneUpdate, ours)[0] == _decode(SceneUpdate, sdk)[0]


def test_primitive_block_equals_encoding_each_primitive_anew():
    from dynabarn.recording import wire

    rng = np.random.default_rng(1)
    color = wire.color(1, 0, 0, 1)
    parts = [(8, wire.cube, 0.5), (10, wire.cylinder, 0.35), (10, wire.cylinder, 0.5)]
    block = wire.PrimitiveBlock(
        [(f, enc(wire.pose(0.0, 0.0, z, 0, 0, 0.3, 0.95), wire.vector3(1, 1, 1), color)) for f, enc, z in parts]
    )
    for _ in range(3):
        xy = rng.uniform(-10, 10, (3, 2))
        expected = b"".join(
            wire.length_delimited(f, enc(wire.pose(x, y, z, 0, 0, 0.3, 0.95), wire.vector3(1, 1, 1), color))
            for (f, enc, z), (x, y) in zip(parts, xy.tolist(), strict=True)
        )
        assert block.encode(xy) == expected
    assert wire.PrimitiveBlock([]).encode(np.zeros((0, 2))) == b""


def test_frame_transforms_match_sdk():
    from foxglove.messages import FrameTransform, FrameTransforms

    from dynabarn.recording.scene import FrameTree

    ns, yaw = 3_250_000_000, 2.5
    qz, qw = math.sin(yaw / 2), math.cos(yaw / 2)
    ours = FrameTree(0.12, 0.0, 0.3).message(ns, 4.5, -1.25, qz, qw)
    ts = Timestamp(sec=3, nsec=250_000_000)
    identity = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    sdk = FrameTransforms(
        transforms=[
            FrameTransform(
                timestamp=ts, parent_frame_id="world", child_frame_id="odom",
                translation=Vector3(x=0.0, y=0.0, z=0.0), rotation=identity,
            ),
            FrameTransform(
                timestamp=ts, parent_frame_id="odom", child_frame_id="base_link",
                translation=Vector3(x=4.5, y=-1.25, z=0.0), rotation=Quaternion(x=0.0, y=0.0, z=qz, w=qw),
            ),
            FrameTransform(
                timestamp=ts, parent_frame_id="base_link", child_frame_id="laser",
                translation=Vector3(x=0.12, y=0.0, z=0.3), rotation=identity,
            ),
        ]
    ).encode()  # fmt: skip
    assert _decode(FrameTransforms, ours)[0] == _decode(FrameTransforms, sdk)[0]


def test_plans_match_sdk():
    from foxglove.messages import LinePrimitive, LinePrimitiveLineType, Point3

    from dynabarn.recording.scene import plans_update

    local = np.array([[1.0, 2.0], [1.5, 2.25], [2.0, 2.75]])
    glob = np.array([[1.0, 2.0], [3.0, 4.0]])
    ours = plans_update(1_100_000_000, {"local_plan": local, "global_plan": glob})

    def line(points, z, width, color):
        return LinePrimitive(
            type=LinePrimitiveLineType.LineStrip,
            pose=_pose(0.0, 0.0, 0.0, 0.0),
            thickness=width,
            scale_invariant=False,
            points=[Point3(x=x, y=y, z=z) for x, y in points],
            color=color,
        )

    ts = Timestamp(sec=1, nsec=100_000_000)
    sdk = SceneUpdate(
        entities=[
            SceneEntity(
                timestamp=ts, frame_id="world", id="global_plan",
                lines=[line(glob, 0.03, 0.05, Color(r=0.2, g=0.45, b=1.0, a=0.8))],
            ),
            SceneEntity(
                timestamp=ts, frame_id="world", id="local_plan",
                lines=[line(local, 0.06, 0.06, Color(r=1.0, g=0.78, b=0.0, a=1.0))],
            ),
        ]
    ).encode()  # fmt: skip
    assert _decode(SceneUpdate, ours)[0] == _decode(SceneUpdate, sdk)[0]
    # No plan this tick: the entities are sent empty, so the last plan does not linger.
    _, empty = _decode(SceneUpdate, plans_update(0, {}))
    assert [e.id for e in empty.entities] == ["global_plan", "local_plan"]
    assert all(len(e.lines) == 0 for e in empty.entities)
