"""Offscreen videos of recorded episodes with `mujoco.Renderer` (EGL or OSMesa, no GPU).

A recording holds everything needed: the world (metadata and keyframes), the obstacles'
clock offset and the robot's poses. The world is recompiled from that, the obstacles are
replayed from their schedules at each frame time (exact, not interpolated from the 10 Hz
updates), the robot is put at its recorded pose (interpolated between the 50 Hz poses),
and each frame is drawn with the goal region, the robot's path so far and short trails
behind the obstacles. Cameras: `top` (the whole arena from above) or `follow` (behind the
robot). Output: `.mp4` (H.264 through imageio-ffmpeg's bundled ffmpeg) or `.gif`.

MuJoCo picks its OpenGL platform when first imported: on a machine without a display set
`MUJOCO_GL=egl` (or `osmesa`) before importing mujoco; `dynabarn-render` does so itself.
"""

from __future__ import annotations

import itertools
import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.mjcf import load_model, write_world
from dynabarn.recording import Recording, attached_world, obstacle_track, pose_track, recorded_world
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import WorldSpec

TRAIL_SECONDS = 2.0


@dataclass(frozen=True, slots=True)
class VideoInfo:
    path: Path
    frames: int
    fps: float
    duration: float
    width: int
    height: int


def _interpolate(t: np.ndarray, xy: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Recorded centres (T, n, 2) at times t, linearly interpolated to `at` (K,): (K, n, 2)."""
    if len(t) == 0:
        raise DynabarnError("the recording holds no obstacle updates")
    k = np.clip(np.searchsorted(t, at, side="right") - 1, 0, len(t) - 1)
    k1 = np.minimum(k + 1, len(t) - 1)
    span = np.where(k1 > k, t[k1] - t[k], 1.0)
    u = np.clip((at - t[k]) / span, 0.0, 1.0)[:, None, None]
    return xy[k] + (xy[k1] - xy[k]) * u


def recorded_model(rec: Recording, world: WorldSpec) -> mujoco.MjModel:
    """The episode's MuJoCo model: the world file attached to the recording (the exact file
    that ran), else one compiled anew from the recorded world description."""
    attached = attached_world(rec)
    if attached is not None:
        name, data = attached
        return load_model(rec.path.parent / name, beam_sensors=False, data=data)
    with tempfile.TemporaryDirectory() as tmp:
        xml = Path(tmp) / f"{world.name}.xml"
        write_world(world, xml)
        return load_model(xml, beam_sensors=False)


def _add_geom(scene: mujoco.MjvScene, gtype: int, size, pos, rgba, mat=None) -> None:
    if scene.ngeom >= scene.maxgeom:
        return
    mujoco.mjv_initGeom(
        scene.geoms[scene.ngeom],
        gtype,
        np.asarray(size, float),
        np.asarray(pos, float),
        np.eye(3).ravel() if mat is None else mat,
        np.asarray(rgba, np.float32),
    )
    scene.ngeom += 1


def _add_line(scene: mujoco.MjvScene, a, b, width: float, rgba) -> None:
    if scene.ngeom >= scene.maxgeom:
        return
    g = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(
        g, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(), np.asarray(rgba, np.float32)
    )
    mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_CAPSULE, width, np.asarray(a, float), np.asarray(b, float))
    scene.ngeom += 1


CAMERAS = ("top", "follow")
"""top: the whole arena from above; follow: behind and above the robot."""


def place_camera(cam: mujoco.MjvCamera, camera: str, pose) -> None:
    """Point the free camera `cam` for `camera` (one of CAMERAS) at robot pose (x, y, yaw)."""
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    x, y, yaw = (float(v) for v in pose[:3])
    if camera == "top":
        cam.lookat[:] = [0.5, 0.0, 0.0]
        cam.distance, cam.elevation, cam.azimuth = 27.0, -90.0, 90.0
    else:
        cam.lookat[:] = [x, y, 0.3]
        cam.distance, cam.elevation, cam.azimuth = 7.0, -35.0, math.degrees(yaw)


# Over 80 lines on purpose: the scene set-up and the frame loop share the renderer, the
# model and the trails; the helpers above hold the parts that stand alone.
def render_recording(
    rec: Recording,
    out: Path,
    *,
    camera: str = "top",
    fps: float = 20.0,
    width: int = 640,
    height: int = 480,
    progress=None,
) -> VideoInfo:
    """Render the recorded episode to `out` (.mp4 or .gif); returns what was written."""
    import imageio.v2 as imageio

    out = Path(out)
    if out.suffix.lower() not in (".mp4", ".gif"):
        raise DynabarnError(f"video must end in .mp4 or .gif, got {out.name!r}")
    if camera not in CAMERAS:
        raise DynabarnError(f"unknown camera {camera!r}; available: {', '.join(CAMERAS)}")
    world = recorded_world(rec)
    meta = rec.metadata
    t_pose, track = pose_track(rec)
    duration = float(t_pose[-1])
    n_frames = math.floor(duration * fps + 1e-9) + 1
    frame_times = np.arange(n_frames) / fps

    model = recorded_model(rec, world)
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    data = mujoco.MjData(model)
    trail_steps = np.arange(-TRAIL_SECONDS, 0.0001, 0.25)
    trail_times = np.clip(frame_times[:, None] + trail_steps, 0, None).ravel()
    if any(o.reactive for o in world.obstacles):
        # Reactive obstacles went where the robot made them go: play what was recorded.
        t_obs, xy_obs = obstacle_track(rec, world)
        obstacle_xy, trail_xy = _interpolate(t_obs, xy_obs, frame_times), _interpolate(t_obs, xy_obs, trail_times)
    else:  # scripted ones exactly, from their schedules
        player = SchedulePlayer(world, clock_offset=float(meta.get("clock_offset", 0.0)))
        obstacle_xy, _ = player.positions_at(frame_times)
        trail_xy, _ = player.positions_at(trail_times)
    trail_xy = trail_xy.reshape(n_frames, len(trail_steps), -1, 2)
    robot = np.column_stack([np.interp(frame_times, t_pose, track[:, k]) for k in range(3)])
    n_obs = len(world.obstacles)
    goal = world.layout.goal
    tol = meta.get("protocol", {}).get("goal_tolerance", 1.0)

    cam = mujoco.MjvCamera()
    opt = mujoco.MjvOption()
    opt.sitegroup[:] = 0  # the laser sites would clutter the picture
    writer = (
        imageio.get_writer(out, fps=fps, codec="libx264", quality=7, macro_block_size=8, pixelformat="yuv420p")
        if out.suffix.lower() == ".mp4"
        else imageio.get_writer(out, mode="I", duration=1000.0 / fps, loop=0)
    )
    frames = range(n_frames) if progress is None else progress(range(n_frames))
    try:
        with mujoco.Renderer(model, height, width) as renderer:
            for k in frames:
                data.qpos[:3] = robot[k]
                data.mocap_pos[:n_obs, :2] = obstacle_xy[k]
                mujoco.mj_kinematics(model, data)
                place_camera(cam, camera, robot[k])
                renderer.update_scene(data, cam, opt)
                scene = renderer.scene
                _add_geom(
                    scene,
                    mujoco.mjtGeom.mjGEOM_CYLINDER,
                    [tol, 0.005, 0],
                    [goal[0], goal[1], 0.006],
                    [0.1, 0.85, 0.2, 0.45],
                )
                past = robot[: k + 1 : max(1, int(fps // 5)), :2]
                for a, b in itertools.pairwise(past):
                    _add_line(scene, [*a, 0.03], [*b, 0.03], 0.04, [0.15, 0.35, 0.95, 1.0])
                for i in range(n_obs):
                    tr = trail_xy[k, :, i]
                    for a, b in itertools.pairwise(tr):
                        _add_line(scene, [*a, 0.02], [*b, 0.02], 0.06, [0.95, 0.45, 0.35, 0.6])
                writer.append_data(renderer.render())
    finally:
        writer.close()
    return VideoInfo(path=out, frames=n_frames, fps=fps, duration=duration, width=width, height=height)
