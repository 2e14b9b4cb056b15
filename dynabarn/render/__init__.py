"""Offscreen pictures of recorded episodes: what each frame shows (frames), the model and
cameras (model), the overlay drawn on the frames (overlay), the video loop (video)."""

from dynabarn.render.model import CAMERAS, NO_GL_PLATFORM, offscreen_renderer, place_camera, recorded_model
from dynabarn.render.video import QUALITIES, VideoInfo, check_video, render_recording

__all__ = [
    "CAMERAS",
    "NO_GL_PLATFORM",
    "QUALITIES",
    "VideoInfo",
    "check_video",
    "offscreen_renderer",
    "place_camera",
    "recorded_model",
    "render_recording",
]
