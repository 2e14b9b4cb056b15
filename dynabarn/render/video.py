"""Offscreen videos of recorded episodes with `mujoco.Renderer` (EGL or OSMesa, no GPU).

Each frame is the MuJoCo scene (world, obstacles with 2 s trails, the robot on a marker
disc with a heading arrow, its path so far, the goal region) plus an overlay: the laser's
returns as dots, a header naming world, planner, protocol and seed, the time and speed, a
legend, and over the last second the outcome. Cameras: `top` (the whole arena from above)
or `follow` (behind the robot). Output: `.mp4` (H.264 through imageio-ffmpeg's bundled
ffmpeg) or `.gif`.

Fast on a software rasteriser: one renderer and one output buffer for all frames, no
multisampling (it doubled llvmpipe's time per frame), no shadows, reflections or skybox,
an untextured floor in the top view, and only the frames written are rendered (the held
final frame is written again, not drawn again).

MuJoCo picks its OpenGL platform when first imported: on a machine without a display set
`MUJOCO_GL=egl` (or `osmesa`) before importing mujoco; `dynabarn-render` does so itself.
"""

from __future__ import annotations

import contextlib
import errno
import itertools
import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.files import staged_path
from dynabarn.metrics import OUTCOME_MESSAGES, Outcome
from dynabarn.recording import Recording, pose_track, recorded_world
from dynabarn.render.frames import frame_tracks
from dynabarn.render.model import CAMERAS, offscreen_renderer, place_camera, recorded_model
from dynabarn.render.overlay import LASER, Overlay, draw_dots, project

QUALITIES = ("fast", "high")
HOLD_SECONDS = 1.5
"""The last frame, with the outcome, is held this long."""
_R = mujoco.mjtRndFlag
_OFF = (_R.mjRND_SHADOW, _R.mjRND_REFLECTION, _R.mjRND_SKYBOX, _R.mjRND_HAZE)
_CAPSULE = mujoco.mjtGeom.mjGEOM_CAPSULE
_EYE = np.eye(3).ravel()
_ZERO = np.zeros(3)


@dataclass(frozen=True, slots=True)
class VideoInfo:
    path: Path
    frames: int
    fps: float
    duration: float
    width: int
    height: int


class _SceneMarks:
    """Geoms added to MuJoCo's scene each frame, written into its geom buffer in place."""

    def __init__(self, scene: mujoco.MjvScene) -> None:
        self.scene = scene

    def _next(self):
        if self.scene.ngeom >= self.scene.maxgeom:
            return None
        g = self.scene.geoms[self.scene.ngeom]
        self.scene.ngeom += 1
        return g

    def geom(self, gtype, size, pos, rgba, mat=_EYE) -> None:
        g = self._next()
        if g is not None:
            mujoco.mjv_initGeom(g, gtype, np.asarray(size, float), np.asarray(pos, float), mat, rgba)

    def polyline(self, xy: np.ndarray, z: float, width: float, rgba: np.ndarray) -> None:
        for a, b in itertools.pairwise(xy.tolist()):
            g = self._next()
            if g is None:
                return
            mujoco.mjv_initGeom(g, _CAPSULE, _ZERO, _ZERO, _EYE, rgba)
            mujoco.mjv_connector(g, _CAPSULE, width, np.array([a[0], a[1], z]), np.array([b[0], b[1], z]))


_GOAL_RGBA = np.array([0.1, 0.85, 0.2, 0.45], np.float32)
_ROBOT_DISC_RGBA = np.array([0.15, 0.35, 0.95, 0.7], np.float32)
_ARROW_RGBA = np.array([0.02, 0.08, 0.35, 1.0], np.float32)
_PATH_RGBA = np.array([0.15, 0.35, 0.95, 1.0], np.float32)
_TRAIL_RGBA = np.array([0.95, 0.45, 0.35, 0.6], np.float32)


def _outcome_line(result: dict | None) -> tuple[str, str]:
    if not result:
        return "error", "UNFINISHED (the recording was cut)"
    outcome = result.get("outcome", "error")
    known = {o.value: o for o in Outcome}
    head = f"{outcome.upper()}: {OUTCOME_MESSAGES[known[outcome]]}" if outcome in known else str(outcome)
    return outcome, f"{head} after {result.get('time', 0.0):.2f} s" + (
        f", score {result['score']:.3f}" if outcome == "success" and result.get("score") is not None else ""
    )


def _header(rec: Recording, world_name: str) -> str:
    meta = rec.metadata or {}
    protocol = meta.get("protocol", {}).get("name", "?")
    return f"{world_name} | {meta.get('planner', '?')} | {protocol} | seed {meta.get('seed', '?')}"


@contextlib.contextmanager
def _writer(out: Path, fps: float):
    """imageio's writer for `out`, closed when the block ends: then ffmpeg writes the rest, so
    a full disk may show there; after a failure its own errors on closing are not added."""
    import imageio.v2 as imageio

    if out.suffix.lower() == ".mp4":
        # macro_block_size 2: H.264 in yuv420p needs even sizes, nothing more (no silent resize).
        writer = imageio.get_writer(out, fps=fps, codec="libx264", quality=7, macro_block_size=2, pixelformat="yuv420p")
    else:
        writer = imageio.get_writer(out, mode="I", duration=1000.0 / fps, loop=0)
    try:
        yield writer
    except BaseException:
        with contextlib.suppress(Exception):
            writer.close()
        _disarm(writer)
        raise
    try:
        writer.close()
    except BaseException:
        _disarm(writer)
        raise
    # ffmpeg reports a failed trailer (a disk full at the very end) only in its own output
    # and exits as if nothing happened: the file says whether it is whole.
    if out.suffix.lower() == ".mp4" and not mp4_is_whole(out):
        raise OSError(errno.EIO, "the encoder did not finish the video (its index is missing: a full disk?)", str(out))


def _disarm(writer) -> None:
    """A writer whose close failed is closed: its finaliser must not write (and fail) again."""
    with contextlib.suppress(AttributeError):  # imageio's ffmpeg writer has no such flag to set
        writer.closed = True
    plugin = getattr(writer, "instance", None)
    if plugin is not None:  # imageio's Pillow plugin: its file is closed here, once
        with contextlib.suppress(Exception):
            plugin._request.finish()
        plugin.close = lambda: None


def mp4_is_whole(path: Path) -> bool:
    """The MP4 file's top-level boxes run exactly to its end and hold the index (`moov`),
    which ffmpeg writes last: what a player needs, and what a cut file lacks."""
    size = path.stat().st_size
    seen = set()
    with open(path, "rb") as f:
        at = 0
        while at < size:
            f.seek(at)
            head = f.read(16)
            if len(head) < 8:
                return False
            length, kind = int.from_bytes(head[:4], "big"), head[4:8]
            if length == 1 and len(head) == 16:  # a 64-bit size follows
                length = int.from_bytes(head[8:16], "big")
            elif length == 0:  # to the end of the file
                length = size - at
            if length < 8:
                return False
            seen.add(kind)
            at += length
    return at == size and b"moov" in seen


def check_video(out: Path, width: int, height: int) -> None:
    """One clear line for a video that cannot be written as asked."""
    if out.suffix.lower() not in (".mp4", ".gif"):
        raise DynabarnError(f"video must end in .mp4 or .gif, got {out.name!r}")
    if out.is_dir():
        raise DynabarnError(f"{out} is a folder, not a video file")
    try:  # before any frame: ffmpeg and Pillow find out only when they write, in many lines
        with tempfile.TemporaryFile(dir=out.parent):
            pass
    except OSError as exc:
        raise DynabarnError(f"cannot write a video into {out.parent}: {exc.strerror or exc}") from None
    if out.suffix.lower() == ".mp4" and (width % 2 or height % 2):
        raise DynabarnError(f"an .mp4 (H.264) needs an even width and height, got {width}x{height}")


# Over 80 lines on purpose: the scene set-up and the frame loop share the renderer, the
# model, the buffer and the per-frame arrays; the helpers above hold the parts that stand alone.
def render_recording(
    rec: Recording,
    out: Path,
    *,
    camera: str = "top",
    fps: float = 20.0,
    width: int = 640,
    height: int = 480,
    quality: str = "fast",
    progress=None,
) -> VideoInfo:
    """Render the recorded episode to `out` (.mp4 or .gif); returns what was written.

    `quality`: `fast` (no multisampling, 12-facet round shapes, plain floor from above) or
    `high` (MuJoCo's defaults: 4x multisampling, 28 facets, the textured floor), about 3x
    slower on a software rasteriser."""
    out = Path(out)
    check_video(out, width, height)
    if camera not in CAMERAS:
        raise DynabarnError(f"unknown camera {camera!r}; available: {', '.join(CAMERAS)}")
    if quality not in QUALITIES:
        raise DynabarnError(f"unknown quality {quality!r}; available: {', '.join(QUALITIES)}")
    world = recorded_world(rec)
    meta = rec.metadata or {}
    model = recorded_model(rec, world)
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    if quality == "fast":
        model.vis.quality.offsamples = 0
        model.vis.quality.numslices, model.vis.quality.numstacks = 12, 4  # round shapes from 12 facets
    if camera == "top" and quality == "fast":  # a 512 px checker costs a third of a frame, says nothing from 31 m up
        floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        if floor >= 0:
            model.geom_matid[floor] = -1
            model.geom_rgba[floor] = (0.8, 0.8, 0.78, 1.0)
    data = mujoco.MjData(model)

    duration = float(pose_track(rec)[0][-1])
    n_frames = math.floor(duration * fps + 1e-9) + 1
    tracks = frame_tracks(rec, world, np.arange(n_frames) / fps)
    n_obs = len(world.obstacles)
    goal = world.layout.goal
    tol = meta.get("protocol", {}).get("goal_tolerance", 1.0)
    length = (meta.get("robot", {}).get("footprint") or [0.508, 0.43])[0]
    laser_z = meta.get("robot", {}).get("laser_z", 0.3)
    path_every = max(1, int(fps // 5))
    overlay = Overlay(width, height, _header(rec, world.name))
    outcome = _outcome_line(rec.result)
    n_hold = max(1, round(HOLD_SECONDS * fps))

    cam = mujoco.MjvCamera()
    opt = mujoco.MjvOption()
    opt.sitegroup[:] = 0  # the laser sites would clutter the picture
    frame = np.empty((height, width, 3), np.uint8)
    # Written beside `out` and renamed when whole: a video already there is replaced only by
    # a finished one, and a killed or failed render leaves nothing under its name.
    frames = range(n_frames) if progress is None else progress(range(n_frames))
    try:
        with (
            staged_path(out) as part,
            _writer(part, fps) as writer,
            offscreen_renderer(model, height, width) as renderer,
        ):
            scene = renderer.scene
            marks = _SceneMarks(scene)
            for k in frames:
                x, y, yaw = tracks.robot[k].tolist()
                data.qpos[:3] = (x, y, yaw)
                data.mocap_pos[:n_obs, :2] = tracks.obstacles[k]
                mujoco.mj_kinematics(model, data)
                place_camera(cam, camera, tracks.robot[k])
                renderer.update_scene(data, cam, opt)
                for flag in _OFF:
                    scene.flags[flag] = 0
                marks.geom(mujoco.mjtGeom.mjGEOM_CYLINDER, [tol, 0.005, 0], [goal[0], goal[1], 0.006], _GOAL_RGBA)
                if camera == "top":  # the robot, legible from 31 m up: a disc under it, an arrow ahead
                    marks.geom(mujoco.mjtGeom.mjGEOM_CYLINDER, [0.7, 0.004, 0], [x, y, 0.008], _ROBOT_DISC_RGBA)
                    c, s = math.cos(yaw), math.sin(yaw)
                    # An arrow points along its z: columns (x, y, z) = (-sin, cos, 0), (0, 0, 1), (cos, sin, 0).
                    heading = np.array([-s, 0.0, c, c, 0.0, s, 0.0, 1.0, 0.0])
                    marks.geom(mujoco.mjtGeom.mjGEOM_ARROW, [0.15, 0.15, 4 * length], [x, y, 0.3], _ARROW_RGBA, heading)
                marks.polyline(tracks.robot[: k + 1 : path_every, :2], 0.03, 0.07, _PATH_RGBA)
                for i in range(n_obs):
                    marks.polyline(tracks.trails[k, :, i], 0.02, 0.06, _TRAIL_RGBA)
                renderer.render(out=frame)
                j = tracks.scan_index[k]
                if j >= 0:
                    points = tracks.scan_points[j]
                    xyz = np.column_stack([points, np.full(len(points), laser_z)])
                    draw_dots(frame, project(scene.camera[0], xyz, width, height), LASER, size=max(2, width // 320))
                last = k == n_frames - 1
                overlay.apply(frame, float(tracks.times[k]), float(tracks.speed[k]), outcome if last else None)
                for _ in range(n_hold if last else 1):
                    writer.append_data(frame)
    except (OSError, RuntimeError) as exc:  # ffmpeg's many lines (a full disk): one
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise DynabarnError(f"cannot write {out}: {first}") from None
    return VideoInfo(path=out, frames=n_frames + n_hold - 1, fps=fps, duration=duration, width=width, height=height)
