"""Top-down pictures of worlds, in the manner of the paper's Fig. 1 and Fig. 3."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import Interpolation, Obstacle, WorldSpec

# Spawn points of the two protocols (docs/concepts/protocols.md); drawn for orientation only.
_SPAWNS = {"barn": (11.0, 0.0), "paper2022": (12.0, 0.0)}


def footprint_outline(obstacle: Obstacle, centre, n_arc: int = 12) -> np.ndarray:
    """The obstacle's footprint (a rounded rectangle) as a closed polygon (k, 2) at `centre`."""
    hl, hw = obstacle.half_extents
    r = obstacle.radius
    pts = []
    for k, (sx, sy) in enumerate(((1, 1), (-1, 1), (-1, -1), (1, -1))):
        corner = np.array([sx * hl, sy * hw])
        if r > 0:
            a = np.linspace(k * np.pi / 2, (k + 1) * np.pi / 2, n_arc)
            pts.append(corner + r * np.column_stack([np.cos(a), np.sin(a)]))
        else:
            pts.append(corner[None])
    local = np.concatenate(pts)
    c, s = np.cos(obstacle.yaw), np.sin(obstacle.yaw)
    return np.asarray(centre) + local @ np.array([[c, s], [-s, c]])


def plot_world(world: WorldSpec, out: Path | str, *, dpi: int = 120) -> Path:
    """Write a PNG of the world: walls, goal, spawns, each obstacle's path with its start
    (filled circle at the obstacle's size) and direction (arrow at mid-path)."""
    # A Figure of its own, not pyplot: no global backend switch, no figure registry.
    from matplotlib import colormaps
    from matplotlib.collections import PatchCollection
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Polygon, Rectangle

    fig = Figure(figsize=(7.2, 6.4), dpi=dpi)
    ax = fig.subplots()
    for wall in world.layout.walls:
        (cx, cy), (sx, sy, _) = wall.centre, wall.size
        ax.add_patch(Rectangle((cx - sx / 2, cy - sy / 2), sx, sy, color="0.45"))
    if world.layout.cylinders:
        static = [Circle((x, y), r) for x, y, r in world.layout.cylinders]
        ax.add_collection(PatchCollection(static, color="0.3", linewidth=0))
    cmap = colormaps.get_cmap("tab20")
    player = SchedulePlayer(world)
    for i, o in enumerate(world.obstacles):
        color = cmap(i % 20)
        tr = o.trajectory
        if world.interpolation is Interpolation.SPLINE:
            ts = np.linspace(0, tr.duration, 400, endpoint=False)
            path = np.array([player.state(t)[0][i] for t in ts])
        else:
            path = tr.xy
        ax.plot(path[:, 0], path[:, 1], "-", color=color, lw=1.4)
        ax.plot(tr.xy[:, 0], tr.xy[:, 1], ".", color=color, ms=4)
        if o.shape == "cylinder":
            ax.add_patch(Circle(tuple(tr.xy[0]), o.radius, color=color, alpha=0.55))
        else:
            ax.add_patch(Polygon(footprint_outline(o, tr.xy[0]), color=color, alpha=0.55))
        mid = len(path) // 2
        a, b = path[max(mid - 1, 0)], path[mid]
        ax.annotate("", xy=tuple(b), xytext=tuple(a), arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.5})
    gx, gy = world.layout.goal
    ax.plot(gx, gy, "*", color="tab:green", ms=16, label="goal")
    for name, (sx, sy) in _SPAWNS.items():
        ax.plot(
            sx,
            sy,
            ">" if name == "barn" else "<",
            ms=9,
            color="k" if name == "barn" else "0.5",
            label=f"spawn ({name})",
        )
    half = world.layout.arena_half_size
    ax.set_xlim(-half - 1, half + 3)
    ax.set_ylim(-half - 1, half + 1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(
        f"{world.name}: {world.difficulty.value}, {len(world.obstacles)} obstacles, "
        + (f"{len(world.layout.cylinders)} static, " if world.layout.cylinders else "")
        + f"{world.profile_set} ({world.interpolation.value}, {world.end_behavior.value})",
        fontsize=10,
    )
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out)
    return out
