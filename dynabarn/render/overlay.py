"""Drawing on rendered frames: world points projected through MuJoCo's camera (the laser's
returns as dots, a few thousand per second of video at no cost to the 3D scene) and the
text that makes a video explain itself (what ran, the time, the speed, the outcome).

The header and legend are drawn once with Pillow and pasted into every frame; only the
time line is drawn per frame, on a small strip.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from PIL import Image, ImageDraw, ImageFont

TEXT = (255, 255, 255)
PANEL = (20, 22, 28)
LASER = (230, 0, 230)
ROBOT = (38, 90, 242)
OBSTACLE = (217, 38, 31)
GOAL = (26, 204, 51)
OUTCOME_COLORS = {
    "success": (26, 160, 60),
    "collision": (200, 30, 30),
    "timeout": (220, 140, 0),
    "error": (120, 120, 120),
}


def project(camera: mujoco.MjvGLCamera, points: np.ndarray, width: int, height: int) -> np.ndarray:
    """Pixel (column, row) of world points (n, 3) seen by an OpenGL camera of the scene
    (`renderer.scene.camera[0]` after `update_scene`); points behind it get -1."""
    pos, forward, up = np.asarray(camera.pos), np.asarray(camera.forward), np.asarray(camera.up)
    right = np.cross(forward, up)
    rel = np.asarray(points, dtype=np.float64) - pos
    depth = rel @ forward
    x, y = rel @ right, rel @ up
    half_h = (camera.frustum_top - camera.frustum_bottom) / 2
    centre_v = (camera.frustum_top + camera.frustum_bottom) / 2
    # MuJoCo fills the width from the viewport's aspect unless the camera sets it.
    half_w = camera.frustum_width or half_h * width / height
    if camera.orthographic:
        u, v = x, y
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            u, v = camera.frustum_near * x / depth, camera.frustum_near * y / depth
    col = (u - camera.frustum_center + half_w) / (2 * half_w) * width
    row = (centre_v + half_h - v) / (2 * half_h) * height
    out = np.column_stack([col, row])
    out[~(depth > camera.frustum_near)] = -1
    return out


def draw_dots(frame: np.ndarray, pixels: np.ndarray, color, size: int = 2) -> None:
    """Square dots of `size` px at pixels (n, 2), in place, all at once."""
    h, w = frame.shape[:2]
    base = np.floor(pixels).astype(np.int64)
    offsets = np.arange(size) - size // 2
    cols = (base[:, 0:1] + offsets[None, :])[:, None, :]
    rows = (base[:, 1:2] + offsets[None, :])[:, :, None]
    cols, rows = np.broadcast_arrays(cols, rows)
    inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    frame[rows[inside], cols[inside]] = color


def _font(size: int) -> ImageFont.ImageFont:
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError):  # Pillow without FreeType: the fixed bitmap font
        return ImageFont.load_default()


@dataclass
class Overlay:
    """The text on every frame: a header (world, planner, protocol, seed), a line with the
    time and speed, a legend, and at the end the outcome."""

    width: int
    height: int
    header: str
    legend: tuple[tuple[str, tuple[int, int, int]], ...] = (
        ("robot, path", ROBOT),
        ("obstacles, trails", OBSTACLE),
        ("laser returns", LASER),
        ("goal", GOAL),
    )

    def __post_init__(self) -> None:
        self.font_size = max(9, min(22, self.height // 30))
        self.font = _font(self.font_size)
        self.line = int(self.font_size * 1.35)
        self._header = self._strip([(self.header, TEXT)], 2)
        self._legend = self._legend_strip()

    def _strip(self, lines: list[tuple[str, tuple[int, int, int]]], n_lines: int, fill=PANEL) -> np.ndarray:
        image = Image.new("RGB", (self.width, self.line * n_lines + 4), fill)
        draw = ImageDraw.Draw(image)
        for i, (text, color) in enumerate(lines):
            draw.text((6, 2 + i * self.line), text, fill=color, font=self.font)
        return np.asarray(image)

    def _legend_strip(self) -> np.ndarray:
        image = Image.new("RGB", (self.width, self.line + 4), PANEL)
        draw = ImageDraw.Draw(image)
        x = 6
        for text, color in self.legend:
            s = self.font_size * 2 // 3
            top = 2 + (self.line - s) // 2
            draw.rectangle((x, top, x + s, top + s), fill=color)
            x += s + 4
            draw.text((x, 2), text, fill=TEXT, font=self.font)
            x += int(draw.textlength(text, font=self.font)) + 14
        return np.asarray(image)

    def apply(self, frame: np.ndarray, t: float, speed: float, outcome: tuple[str, str] | None = None) -> None:
        """Draw the overlay on `frame` (H, W, 3) in place; `outcome`: (outcome, its line) at the end."""
        header = self._header
        frame[: header.shape[0]] = header
        if outcome is None:
            status = self._strip([(f"t = {t:6.2f} s    v = {speed:5.2f} m/s", TEXT)], 1)
        else:  # the outcome takes the time line's place, in its colour
            kind, text = outcome
            status = self._strip([(text, TEXT)], 1, fill=OUTCOME_COLORS.get(kind, PANEL))
        frame[self.line : self.line + status.shape[0]] = status
        legend = self._legend
        frame[-legend.shape[0] :] = legend
