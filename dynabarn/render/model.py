"""The episode's MuJoCo model for pictures, and the cameras that look at it."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import mujoco

from dynabarn.errors import DynabarnError
from dynabarn.mjcf import load_model, write_world
from dynabarn.recording import Recording, attached_world
from dynabarn.worlds.spec import WorldSpec

NO_GL_PLATFORM = (
    "offscreen rendering needs an OpenGL platform for MuJoCo and none is loaded (there is no display): "
    "set MUJOCO_GL=egl (or osmesa) before anything imports mujoco"
)


def offscreen_gl_without_a_display() -> None:
    """Where there is no display and MUJOCO_GL is unset, MuJoCo (which reads MUJOCO_GL once,
    when first imported) has picked GLFW, which cannot open a context: take EGL (Mesa, no GPU
    needed) for its offscreen renderer instead, as the commands do before importing it
    (`cli.common.prefer_offscreen_gl`). An explicit MUJOCO_GL, or a display, is left alone."""
    import os

    from dynabarn.provenance import has_display

    if os.environ.get("MUJOCO_GL") or has_display():
        return
    try:
        from mujoco.egl import GLContext
        from mujoco.rendering.classic import gl_context
    except (ImportError, RuntimeError, OSError, AttributeError):  # no EGL here: the error below says what to set
        return
    gl_context.GLContext = GLContext
    os.environ["MUJOCO_GL"] = "egl"


def offscreen_renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """MuJoCo's offscreen renderer (on EGL where there is no display and MUJOCO_GL is unset:
    `offscreen_gl_without_a_display`), or one line saying what to set where MuJoCo has no
    OpenGL platform."""
    offscreen_gl_without_a_display()
    try:
        return mujoco.Renderer(model, height, width)
    except mujoco.FatalError as e:
        if "OpenGL platform" not in str(e):
            raise
        raise DynabarnError(NO_GL_PLATFORM) from None


CAMERAS = ("top", "follow")
"""top: the whole arena from above; follow: behind and above the robot."""


def place_camera(cam: mujoco.MjvCamera, camera: str, pose) -> None:
    """Point the free camera `cam` for `camera` (one of CAMERAS) at robot pose (x, y, yaw)."""
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    x, y, yaw = (float(v) for v in pose[:3])
    if camera == "top":
        cam.lookat[:] = [1.0, 0.0, 0.0]  # the floor's centre
        # 31 m up: the 20 m arena and the spawn beyond it, with room for a video's text strips.
        cam.distance, cam.elevation, cam.azimuth = 31.0, -90.0, 90.0
    else:
        cam.lookat[:] = [x, y, 0.3]
        cam.distance, cam.elevation, cam.azimuth = 7.0, -35.0, math.degrees(yaw)


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
