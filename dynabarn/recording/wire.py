"""Protobuf wire encoding of the foxglove messages the recorder writes every tick.

The recorder writes ~10,000 poses, 1,000 scans and 1,000 obstacle updates per 100 s of
simulated time. Building foxglove-sdk message objects field by field costs more than the
physics; these encoders write the same protobuf bytes with a few `struct.pack` calls
(the scan's 720 ranges go in as one packed-double block straight from numpy). They
encode exactly the schemas foxglove-sdk ships (`foxglove.LaserScan`, `foxglove.PoseInFrame`,
`foxglove.SceneUpdate`), which the recorder registers on its channels; a test decodes
them with those schemas and compares with foxglove-sdk's own messages.

Proto3 allows scalar fields with default values to be written explicitly; we write every
double, so each message has a fixed layout.
"""

from __future__ import annotations

import functools
import struct

import numpy as np

_LEN = 2  # wire type of length-delimited fields
_F64 = 1  # wire type of 64-bit fields

# Vector3 {x=1, y=2, z=3} and Quaternion {x=1, y=2, z=3, w=4}, doubles: fixed 27 / 36 bytes.
_VEC3 = struct.Struct("<BdBdBd")
_QUAT = struct.Struct("<BdBdBdBd")
# Pose {position=1: Vector3, orientation=2: Quaternion}: fixed 67 bytes.
_POSE = struct.Struct("<BB" + "BdBdBd" + "BB" + "BdBdBdBd")
_POSE_LEN = _POSE.size
_COLOR = struct.Struct("<BdBdBdBd")
_DOUBLE = struct.Struct("<Bd")


def _key(field: int, wire_type: int) -> int:
    return (field << 3) | wire_type


@functools.lru_cache(maxsize=4096)
def _varint_slow(n: int) -> bytes:
    """Cached: timestamps' nanoseconds repeat every second (50 values at the pose rate)."""
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        if n:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


_SMALL_VARINTS = [_varint_slow(n) for n in range(1 << 14)]


def varint(n: int) -> bytes:
    """Protobuf base-128 varint of a non-negative integer (table lookup below 16384)."""
    return _SMALL_VARINTS[n] if n < 16384 else _varint_slow(n)


def length_delimited(field: int, payload: bytes) -> bytes:
    return bytes((_key(field, _LEN),)) + varint(len(payload)) + payload


def timestamp(ns: int) -> bytes:
    """google.protobuf.Timestamp body from nanoseconds (zero fields omitted, as proto3 does)."""
    sec, nsec = divmod(ns, 1_000_000_000)
    out = b""
    if sec:
        out += b"\x08" + varint(sec)
    if nsec:
        out += b"\x10" + varint(nsec)
    return out


def string(field: int, text: str) -> bytes:
    return length_delimited(field, text.encode())


def pose(x: float, y: float, z: float, qx: float, qy: float, qz: float, qw: float) -> bytes:
    """foxglove.Pose body (67 bytes)."""
    return _POSE.pack(
        _key(1, _LEN), _VEC3.size, 0x09, x, 0x11, y, 0x19, z,
        _key(2, _LEN), _QUAT.size, 0x09, qx, 0x11, qy, 0x19, qz, 0x21, qw,
    )  # fmt: skip


def vector3(x: float, y: float, z: float) -> bytes:
    return _VEC3.pack(0x09, x, 0x11, y, 0x19, z)


def color(r: float, g: float, b: float, a: float) -> bytes:
    return _COLOR.pack(0x09, r, 0x11, g, 0x19, b, 0x21, a)


def pose_in_frame(ns: int, frame: bytes, pose_body: bytes) -> bytes:
    """foxglove.PoseInFrame: timestamp=1, frame_id=2, pose=3. `frame` is a pre-encoded field 2."""
    return length_delimited(1, timestamp(ns)) + frame + bytes((_key(3, _LEN), _POSE_LEN)) + pose_body


def laser_scan(
    ns: int, frame: bytes, pose_body: bytes, start_angle: float, end_angle: float, ranges: np.ndarray
) -> bytes:
    """foxglove.LaserScan with packed double ranges (field 6) and no intensities."""
    data = np.ascontiguousarray(ranges, dtype="<f8").tobytes()
    return b"".join(
        (
            length_delimited(1, timestamp(ns)),
            frame,
            bytes((_key(3, _LEN), _POSE_LEN)),
            pose_body,
            _DOUBLE.pack(_key(4, _F64), start_angle),
            _DOUBLE.pack(_key(5, _F64), end_angle),
            bytes((_key(6, _LEN),)) + varint(len(data)),
            data,
        )
    )


def cylinder(pose_body: bytes, size_body: bytes, color_body: bytes) -> bytes:
    """foxglove.CylinderPrimitive body with bottom_scale = top_scale = 1 (a straight cylinder)."""
    return b"".join(
        (
            bytes((_key(1, _LEN), _POSE_LEN)),
            pose_body,
            bytes((_key(2, _LEN), len(size_body))),
            size_body,
            _DOUBLE.pack(_key(3, _F64), 1.0),
            _DOUBLE.pack(_key(4, _F64), 1.0),
            bytes((_key(5, _LEN), len(color_body))),
            color_body,
        )
    )


def scene_update(entities: list[bytes]) -> bytes:
    """foxglove.SceneUpdate with `entities` (field 2), each a SceneEntity body."""
    return b"".join(length_delimited(2, e) for e in entities)


def scene_entity(
    ns: int,
    frame: bytes,
    entity_id: str,
    *,
    cylinders: list[bytes] = (),
    cubes: list[bytes] = (),
    lines: list[bytes] = (),
    primitives: bytes = b"",
) -> bytes:
    """foxglove.SceneEntity: timestamp=1, frame_id=2, id=3, cubes=8, cylinders=10, lines=11,
    then `primitives` already encoded as fields (a `PrimitiveBlock`)."""
    parts = [length_delimited(1, timestamp(ns)), frame, string(3, entity_id)]
    parts += [length_delimited(8, c) for c in cubes]
    parts += [length_delimited(10, c) for c in cylinders]
    parts += [length_delimited(11, c) for c in lines]
    parts.append(primitives)
    return b"".join(parts)


def cube(pose_body: bytes, size_body: bytes, color_body: bytes) -> bytes:
    """foxglove.CubePrimitive body: pose=1, size=2, color=3."""
    return b"".join(
        (
            bytes((_key(1, _LEN), _POSE_LEN)),
            pose_body,
            bytes((_key(2, _LEN), len(size_body))),
            size_body,
            bytes((_key(3, _LEN), len(color_body))),
            color_body,
        )
    )


_X_IN_PRIMITIVE = 5
"""Offset of the pose's x double in a Cube/CylinderPrimitive body: pose key, pose length,
position key, position length, x's tag; y's double follows 9 bytes later."""


class PrimitiveBlock:
    """The primitives of a SceneEntity (field, body) whose poses change only in x and y.

    Encoded once; each message rewrites only the 16 bytes of x and y per primitive, all
    primitives in one numpy assignment, so an obstacle update costs the same few Python
    calls for 5 obstacles or 20. The bytes equal those of encoding each primitive anew.
    """

    def __init__(self, primitives: list[tuple[int, bytes]]) -> None:
        parts, x_at, offset = [], [], 0
        for field, body in primitives:
            encoded = length_delimited(field, body)
            x_at.append(offset + len(encoded) - len(body) + _X_IN_PRIMITIVE)
            parts.append(encoded)
            offset += len(encoded)
        self._buffer = bytearray(b"".join(parts))
        self._bytes = np.frombuffer(self._buffer, dtype=np.uint8)
        x = np.asarray(x_at, dtype=np.int64)[:, None]
        self._index = np.concatenate([x + np.arange(8), x + 9 + np.arange(8)], axis=1).ravel()

    def encode(self, xy: np.ndarray) -> bytes:
        """The block's bytes with positions xy (n, 2) [m], in the primitives' order."""
        self._bytes[self._index] = np.ascontiguousarray(xy, dtype="<f8").view(np.uint8).ravel()
        return bytes(self._buffer)


def frame_transform(ts: bytes, parent: bytes, child: bytes, translation: bytes, rotation: bytes) -> bytes:
    """foxglove.FrameTransform body: timestamp=1 (an encoded Timestamp field), parent=2,
    child=3 (pre-encoded string fields), translation=4 (Vector3 body), rotation=5 (Quaternion body)."""
    return b"".join(
        (
            ts,
            parent,
            child,
            bytes((_key(4, _LEN), len(translation))),
            translation,
            bytes((_key(5, _LEN), len(rotation))),
            rotation,
        )
    )


def quaternion(x: float, y: float, z: float, w: float) -> bytes:
    return _QUAT.pack(0x09, x, 0x11, y, 0x19, z, 0x21, w)


def frame_transforms(transforms: list[bytes]) -> bytes:
    """foxglove.FrameTransforms with `transforms` (field 1), each a FrameTransform body."""
    return b"".join(length_delimited(1, t) for t in transforms)


# Point3 {x=1, y=2, z=3} as a repeated field 5 of LinePrimitive: key, length 27, then the
# three tagged doubles; 29 bytes per point, written for all points at once with numpy.
_POINT = np.dtype(
    [("key", "u1"), ("len", "u1"), ("tx", "u1"), ("x", "<f8"), ("ty", "u1"), ("y", "<f8"), ("tz", "u1"), ("z", "<f8")]
)


def line_strip(points_xy: np.ndarray, z: float, thickness: float, color_body: bytes) -> bytes:
    """foxglove.LinePrimitive body: a LINE_STRIP (type 0, omitted as proto3 does) through
    points (n, 2) at height z, in the entity's frame, `thickness` [m] wide."""
    xy = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    pts = np.empty(len(xy), dtype=_POINT)
    pts["key"], pts["len"] = _key(5, _LEN), 27
    pts["tx"], pts["ty"], pts["tz"] = 0x09, 0x11, 0x19
    pts["x"], pts["y"], pts["z"] = xy[:, 0], xy[:, 1], z
    return b"".join(
        (
            bytes((_key(2, _LEN), _POSE_LEN)),
            pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0),
            _DOUBLE.pack(_key(3, _F64), thickness),
            pts.tobytes(),
            bytes((_key(6, _LEN), len(color_body))),
            color_body,
        )
    )
