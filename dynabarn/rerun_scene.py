"""The rerun entities of a DynaBARN scene, one function each: walls, goal and static
cylinders; the robot's body and poses; the moving obstacles by shape; the planner's
tracks. `replay` (a whole recording, in bulk) and `live.rerun_live` (tick by tick) log
through these, so a replay and a live view show the same entities."""

from __future__ import annotations

import numpy as np
import rerun as rr

from dynabarn.recording import obstacle_pose
from dynabarn.recording.scene import TRACK_HEIGHT
from dynabarn.worlds.spec import WorldSpec

TIMELINE = "sim_time"
"""The timeline every entity is logged on: simulated seconds."""


def quat_z(yaw: np.ndarray) -> np.ndarray:
    """(n, 4) xyzw quaternions of rotations by yaw about z."""
    return np.column_stack([np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2), np.cos(yaw / 2)])


def time_column(times: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(TIMELINE, duration=times)


def log_static_world(meta: dict, stream: rr.RecordingStream) -> None:
    """Walls, goal and the description; static."""
    layout = meta["world"]["layout"]
    walls = layout["walls"]
    stream.log(
        "world/walls",
        rr.Boxes3D(
            centers=[[w["centre"][0], w["centre"][1], w["size"][2] / 2] for w in walls],
            sizes=[w["size"] for w in walls],
            colors=[(140, 140, 155)] * len(walls),
            fill_mode="solid",
        ),
        static=True,
    )
    gx, gy = layout["goal"]
    tol = meta["protocol"]["goal_tolerance"]
    stream.log(
        "world/goal",
        rr.Cylinders3D(lengths=[0.02], radii=[tol], centers=[[gx, gy, 0.01]], colors=[(30, 200, 60, 120)]),
        static=True,
    )
    static = np.asarray(layout.get("cylinders", []), dtype=np.float64).reshape(-1, 3)
    if len(static):  # static BARN or mixed worlds
        stream.log(
            "world/static_obstacles",
            rr.Cylinders3D(
                centers=np.column_stack([static[:, :2], np.full(len(static), 0.5)]),
                radii=static[:, 2],
                lengths=np.ones(len(static)),
                colors=[(140, 140, 155)],
                fill_mode="solid",
            ),
            static=True,
        )
    stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)


def log_robot_poses(stream: rr.RecordingStream, run: str, t: np.ndarray, xy: np.ndarray, yaw: np.ndarray) -> None:
    """The robot's poses at times t (T,): centres xy (T, 2), headings yaw (T,)."""
    stream.send_columns(
        f"{run}/robot",
        indexes=[time_column(t)],
        columns=rr.Transform3D.columns(translation=np.column_stack([xy, np.zeros(len(t))]), quaternion=quat_z(yaw)),
    )


def log_robot_body(stream: rr.RecordingStream, run: str, footprint: tuple[float, float], color) -> None:
    """The robot's footprint box and heading arrow, static under its pose."""
    length, width = footprint
    stream.log(
        f"{run}/robot/body",
        rr.Boxes3D(
            half_sizes=[[length / 2, width / 2, 0.125]], centers=[[0, 0, 0.125]], colors=[color], fill_mode="solid"
        ),
        static=True,
    )
    stream.log(
        f"{run}/robot/heading", rr.Arrows3D(origins=[[0, 0, 0.26]], vectors=[[0.5, 0, 0]], colors=[color]), static=True
    )


_CIRCLE = np.linspace(0.0, 2.0 * np.pi, 25)
_COS, _SIN = np.cos(_CIRCLE), np.sin(_CIRCLE)


def log_tracks(
    stream,
    run: str,
    times: np.ndarray,
    counts: list[int],
    centres: np.ndarray,
    sizes: np.ndarray,
    velocities: np.ndarray,
    *,
    style: bool = True,
) -> None:
    """Tracks against the true obstacles: a circle of each track's size and an arrow of its
    velocity (1 s of motion), `counts[i]` tracks at `times[i]` (rows of centres (N, 2),
    sizes (N,), velocities (N, 2) in time order); `style`: also their colour (static, once)."""
    import rerun as rr

    circles = [
        np.column_stack([x + r * _COS, y + r * _SIN, np.full(len(_COS), TRACK_HEIGHT)])
        for (x, y), r in zip(centres.tolist(), sizes.tolist(), strict=True)
    ]
    index = [time_column(times)]
    strips = rr.LineStrips3D.columns(strips=circles).partition(counts)
    stream.send_columns(f"{run}/tracks", indexes=index, columns=strips)
    origins = np.column_stack([centres, np.full(len(centres), TRACK_HEIGHT)])
    vectors = np.column_stack([velocities, np.zeros(len(velocities))])
    arrows = rr.Arrows3D.columns(origins=origins, vectors=vectors).partition(counts)
    stream.send_columns(f"{run}/track_velocities", indexes=index, columns=arrows)
    if style:
        stream.log(f"{run}/tracks", rr.LineStrips3D.from_fields(colors=[(255, 140, 0)], radii=[0.03]), static=True)
        stream.log(f"{run}/track_velocities", rr.Arrows3D.from_fields(colors=[(255, 140, 0)]), static=True)


def log_obstacles(
    stream: rr.RecordingStream, run: str, world: WorldSpec, t: np.ndarray, xy: np.ndarray, *, style: bool = True
) -> None:
    """The obstacles at times t (T,), centres xy (T, n, 2); `style`: also their colour and fill (static, once)."""
    index = [time_column(t)]
    red = [(215, 40, 30)]
    shapes = np.array([o.shape for o in world.obstacles])
    for shape, entity in (("cylinder", "obstacles"), ("box", "obstacle_boxes"), ("capsule", "obstacle_capsules")):
        sel = np.flatnonzero(shapes == shape)
        if not len(sel):
            continue
        obs = [world.obstacles[i] for i in sel]
        n = len(t)
        centres = xy[:, sel].reshape(-1, 2)
        poses = [obstacle_pose(o) for o in obs]  # the recorder's heights and orientations
        z = np.tile([p[0] for p in poses], n)
        quaternions = np.tile([p[1] for p in poses], (n, 1))
        if shape == "cylinder":
            columns = rr.Cylinders3D.columns(
                centers=np.column_stack([centres, z]),
                radii=np.tile([o.radius for o in obs], n),
                lengths=np.tile([o.height for o in obs], n),
            )
            archetype = rr.Cylinders3D
        elif shape == "box":
            columns = rr.Boxes3D.columns(
                centers=np.column_stack([centres, z]),
                half_sizes=np.tile([[o.half_length, o.half_width, o.height / 2] for o in obs], (n, 1)),
                quaternions=quaternions,
            )
            archetype = rr.Boxes3D
        else:  # a capsule's segment starts at its translation and runs along its local +z
            hl = np.tile([o.half_length for o in obs], n)
            yaw = np.tile([o.yaw for o in obs], n)
            start = centres - hl[:, None] * np.column_stack([np.cos(yaw), np.sin(yaw)])
            columns = rr.Capsules3D.columns(
                translations=np.column_stack([start, z]),
                lengths=2 * hl,
                radii=np.tile([o.radius for o in obs], n),
                quaternions=quaternions,
            )
            archetype = rr.Capsules3D
        stream.send_columns(f"{run}/{entity}", indexes=index, columns=columns.partition([len(sel)] * n))
        if style:
            stream.log(f"{run}/{entity}", archetype.from_fields(colors=red, fill_mode="solid"), static=True)
