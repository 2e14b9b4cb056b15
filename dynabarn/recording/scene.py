"""What the recording draws, encoded: the static scene, the obstacles' primitives, the
planner's plans as line strips and the `/tf` frame tree (foxglove protobuf bytes, `wire`)."""

from __future__ import annotations

import math

import numpy as np

from dynabarn.recording import wire
from dynabarn.recording.topics import FRAMES
from dynabarn.worlds.spec import Obstacle, WorldSpec

WORLD_FRAME = wire.string(2, "world")
LASER_FRAME = wire.string(2, "laser")
IDENTITY_POSE = wire.pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
OBSTACLE_COLOR = wire.color(0.85, 0.15, 0.12, 1.0)
WALL_COLOR = wire.color(0.55, 0.55, 0.6, 1.0)
GOAL_COLOR = wire.color(0.1, 0.8, 0.2, 0.5)
LOCAL_PLAN_COLOR = wire.color(1.0, 0.78, 0.0, 1.0)
GLOBAL_PLAN_COLOR = wire.color(0.2, 0.45, 1.0, 0.8)
TRACK_COLOR = wire.color(1.0, 0.55, 0.0, 0.45)
TRACK_VELOCITY_COLOR = wire.color(1.0, 0.55, 0.0, 1.0)
TRACK_HEIGHT = 1.2
"""[m] Tracks are drawn a little taller than the obstacles (1 m), so a track shows around its
obstacle (in Foxglove's scene and rerun's alike)."""
PLANS = (
    # debug key, colour, height [m], width [m]
    ("global_plan", GLOBAL_PLAN_COLOR, 0.03, 0.05),
    ("local_plan", LOCAL_PLAN_COLOR, 0.06, 0.06),
)


def static_scene(world: WorldSpec, goal_tolerance: float) -> tuple[bytes, bytes]:
    """`/world/static` (walls, goal region, static cylinders) and `/goal`, both at time 0."""
    layout = world.layout
    identity = (0.0, 0.0, 0.0, 1.0)
    cubes = [
        wire.cube(wire.pose(w.centre[0], w.centre[1], w.size[2] / 2, *identity), wire.vector3(*w.size), WALL_COLOR)
        for w in layout.walls
    ]
    gx, gy = layout.goal
    d = 2 * goal_tolerance
    goal = wire.cylinder(wire.pose(gx, gy, 0.005, *identity), wire.vector3(d, d, 0.01), GOAL_COLOR)
    entities = [
        wire.scene_entity(0, WORLD_FRAME, "walls", cubes=cubes),
        wire.scene_entity(0, WORLD_FRAME, "goal", cylinders=[goal]),
    ]
    if layout.cylinders:  # static BARN or mixed worlds
        static = [
            wire.cylinder(wire.pose(x, y, 0.5, *identity), wire.vector3(2 * r, 2 * r, 1.0), WALL_COLOR)
            for x, y, r in layout.cylinders
        ]
        entities.append(wire.scene_entity(0, WORLD_FRAME, "static_obstacles", cylinders=static))
    return wire.scene_update(entities), wire.pose_in_frame(0, WORLD_FRAME, wire.pose(gx, gy, 0.0, *identity))


def obstacle_block(obstacles: list[Obstacle]) -> tuple[wire.PrimitiveBlock, np.ndarray]:
    """The obstacles' primitives, encoded once (each update rewrites only positions), and
    the order of the obstacles in it. Boxes go in the entity's `cubes` (field 8), cylinders
    and capsules (drawn as horizontal cylinders: SceneUpdate has no capsule) in its
    `cylinders` (field 10), each in world order."""
    boxes = [i for i, o in enumerate(obstacles) if o.shape == "box"]
    others = [i for i, o in enumerate(obstacles) if o.shape != "box"]
    primitives = []
    for field_number, encode, indices in ((8, wire.cube, boxes), (10, wire.cylinder, others)):
        for i in indices:
            z, q, size = _primitive_parts(obstacles[i])
            primitives.append((field_number, encode(wire.pose(0.0, 0.0, z, *q), size, OBSTACLE_COLOR)))
    return wire.PrimitiveBlock(primitives), np.array(boxes + others, dtype=np.int64)


def plans_update(ns: int, debug: dict) -> bytes:
    """`/planner/plans`: the local and global plans of a tick's (gridded) debug record as
    line strips; an entity without lines when a plan is absent, so the last one does not linger."""
    entities = []
    for name, color, z, width in PLANS:
        points = np.asarray(debug.get(name, ()), dtype=np.float64)
        lines = []
        if points.ndim == 2 and points.shape[1] >= 2 and len(points) >= 2:
            lines = [wire.line_strip(points[:, :2], z, width, color)]
        entities.append(wire.scene_entity(ns, WORLD_FRAME, name, lines=lines))
    return wire.scene_update(entities)


def tracks_update(ns: int, message: dict) -> bytes:
    """`/perception/tracks/scene`: a tick's (gridded) `/perception/tracks` message as
    translucent cylinders and 1 s velocity lines; empty entities when there are no tracks,
    so old ones do not linger."""
    cylinders, lines = [], []
    for (x, y), (vx, vy), size in zip(message["positions"], message["velocities"], message["sizes"], strict=True):
        body = wire.pose(x, y, TRACK_HEIGHT / 2, 0.0, 0.0, 0.0, 1.0)
        cylinders.append(wire.cylinder(body, wire.vector3(2 * size, 2 * size, TRACK_HEIGHT), TRACK_COLOR))
        lines.append(wire.line_strip(np.array([[x, y], [x + vx, y + vy]]), TRACK_HEIGHT, 0.05, TRACK_VELOCITY_COLOR))
    return wire.scene_update(
        [
            wire.scene_entity(ns, WORLD_FRAME, "tracks", cylinders=cylinders),
            wire.scene_entity(ns, WORLD_FRAME, "track_velocities", lines=lines),
        ]
    )


_TRANSLATION_FIELD = bytes((0x22, 27))  # FrameTransform.translation (field 4): a 27-byte Vector3
_ROTATION_FIELD = bytes((0x2A, 36))  # FrameTransform.rotation (field 5): a 36-byte Quaternion


class FrameTree:
    """`/tf` messages: world -> odom (identity: the pose is the simulator's, no drift) ->
    base_link (the robot) -> laser (its fixed mounting), all three in every message, each
    stamped with the message's time; only the robot's pose is encoded per message."""

    def __init__(self, laser_x: float, laser_y: float, laser_z: float) -> None:
        f = wire.string
        world, odom, base, laser = FRAMES
        identity_q = wire.quaternion(0.0, 0.0, 0.0, 1.0)
        self._world_odom = wire.frame_transform(b"", f(2, world), f(3, odom), wire.vector3(0, 0, 0), identity_q)
        self._odom_base = f(2, odom) + f(3, base) + _TRANSLATION_FIELD
        self._base_laser = wire.frame_transform(
            b"", f(2, base), f(3, laser), wire.vector3(laser_x, laser_y, laser_z), identity_q
        )

    def message(self, ns: int, x: float, y: float, qz: float, qw: float) -> bytes:
        ts = wire.length_delimited(1, wire.timestamp(ns))
        robot = self._odom_base + wire.vector3(x, y, 0.0) + _ROTATION_FIELD + wire.quaternion(0.0, 0.0, qz, qw)
        return (
            wire.length_delimited(1, ts + self._world_odom)
            + wire.length_delimited(1, ts + robot)
            + wire.length_delimited(1, ts + self._base_laser)
        )


def obstacle_pose(o: Obstacle) -> tuple[float, tuple[float, float, float, float]]:
    """Centre height and orientation quaternion (x, y, z, w) of an obstacle's primitive: a
    box turned by its yaw; a capsule's axis (a primitive's z) turned onto x (about y), then
    by its yaw (about z); a cylinder upright."""
    half = o.yaw / 2
    if o.shape == "box":
        return o.height / 2, (0.0, 0.0, math.sin(half), math.cos(half))
    if o.shape == "capsule":
        c = math.sqrt(0.5)
        return o.radius, (-c * math.sin(half), c * math.cos(half), c * math.sin(half), c * math.cos(half))
    return o.height / 2, (0.0, 0.0, 0.0, 1.0)


def _primitive_parts(o: Obstacle) -> tuple[float, tuple[float, float, float, float], bytes]:
    """`obstacle_pose` and the encoded size of the obstacle's SceneUpdate primitive (a
    capsule is drawn as a cylinder as long as the capsule)."""
    if o.shape == "box":
        size = wire.vector3(2 * o.half_length, 2 * o.half_width, o.height)
    elif o.shape == "capsule":
        size = wire.vector3(2 * o.radius, 2 * o.radius, 2 * (o.half_length + o.radius))
    else:
        size = wire.vector3(2 * o.radius, 2 * o.radius, o.height)
    return (*obstacle_pose(o), size)
