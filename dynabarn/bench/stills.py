"""A recorded episode's last moment as a still, for the sweep's report (`bench.report`).

Drawn from above with matplotlib from the MCAP file alone (its attached world, the
robot's poses, the last scan; the obstacles from their schedules at the end time, as
`render.frames` places them): no OpenGL, so it works on a machine without a display or
GPU. One PNG per recording, drawn again only when the recording is newer.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.files import save_atomically
from dynabarn.robot import JACKAL

STILL_DPI = 80


def still_for(recording: Path, folder: Path) -> Path | None:
    """The still of `recording` in `folder`, drawn if missing or older than the recording;
    None when the recording cannot be read (the report lists it without a picture)."""
    still = Path(folder) / f"{Path(recording).stem}.png"
    try:
        if still.is_file() and still.stat().st_mtime >= Path(recording).stat().st_mtime:
            return still
        folder.mkdir(parents=True, exist_ok=True)
        draw_still(Path(recording), still)
    except (DynabarnError, OSError, ValueError):
        return None
    return still


def _footprint(x: float, y: float, yaw: float) -> np.ndarray:
    half = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * (JACKAL.length / 2, JACKAL.width / 2)
    c, s = math.cos(yaw), math.sin(yaw)
    return half @ np.array([[c, s], [-s, c]]) + (x, y)


def outline(x: float, y: float, obstacle) -> np.ndarray:
    """An obstacle's outline in the plane, as it is: its core rectangle (`half_length` along
    its yaw, `half_width` across) grown by its `radius` (a cylinder a circle, a box a
    rectangle, a capsule a stadium; `worlds.spec.Obstacle`). (N, 2) points, counter-clockwise."""
    hl, hw, r = obstacle.half_length, obstacle.half_width, obstacle.radius
    corners = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    arcs = np.linspace(0.0, np.pi / 2, 9)
    points = np.concatenate(
        [
            c + r * np.stack([np.cos(arcs + k * np.pi / 2), np.sin(arcs + k * np.pi / 2)], axis=1)
            for k, c in enumerate(corners)
        ]
    )
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    return points @ np.array([[c, s], [-s, c]]) + (x, y)


def draw_still(recording: Path, out: Path) -> Path:
    """Draw the last moment of `recording` into the PNG `out`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon, Rectangle

    from dynabarn.recording import pose_track, read_recording, recorded_world
    from dynabarn.render.frames import frame_tracks

    rec = read_recording(recording)
    world = recorded_world(rec)
    t_pose, track = pose_track(rec)
    end = np.array([t_pose[-1]])
    frame = frame_tracks(rec, world, end)
    fig, ax = plt.subplots(figsize=(4.0, 4.0), dpi=STILL_DPI)
    layout = world.layout
    for wall in layout.walls:
        corner = (wall.centre[0] - wall.size[0] / 2, wall.centre[1] - wall.size[1] / 2)
        ax.add_patch(Rectangle(corner, wall.size[0], wall.size[1], color="0.35"))
    for cx, cy, r in layout.cylinders:
        ax.add_patch(Circle((cx, cy), r, color="0.5"))
    for obstacle, (ox, oy) in zip(world.obstacles, frame.obstacles[0], strict=True):
        ax.add_patch(Polygon(outline(ox, oy, obstacle), closed=True, color="#c62828", alpha=0.8))
    trails = frame.trails[0]  # (steps, n, 2)
    for k in range(trails.shape[1]):
        ax.plot(trails[:, k, 0], trails[:, k, 1], color="#c62828", alpha=0.3, linewidth=1)
    ax.plot(track[:, 0], track[:, 1], color="#1565c0", linewidth=1.2)
    x, y, yaw = frame.robot[0]
    ax.add_patch(Polygon(_footprint(x, y, yaw), closed=True, color="#1565c0"))
    if frame.scan_index[0] >= 0:
        points = frame.scan_points[frame.scan_index[0]]
        ax.scatter(points[::4, 0], points[::4, 1], s=1, color="#00897b")
    protocol = (rec.metadata or {}).get("protocol")
    tolerance = protocol.get("goal_tolerance", 1.0) if isinstance(protocol, dict) else 1.0
    ax.add_patch(Circle(layout.goal, float(tolerance), fill=False, color="#2e7d32", linestyle="--"))
    result = rec.result or {}
    ax.set_title(f"{result.get('outcome', '?')} at t = {end[0]:.1f} s", fontsize=9)
    half = layout.arena_half_size
    ax.set_xlim(-half - 1, half + 2)
    ax.set_ylim(-half - 1, half + 1)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    fig.tight_layout()
    save_atomically(out, lambda f: fig.savefig(f, format="png", metadata={"Software": None}))
    plt.close(fig)
    return out
