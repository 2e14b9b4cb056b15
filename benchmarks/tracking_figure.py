"""The README's picture of the laser tracker: one tick of `predictive` on a hard world, its
tracks (what the laser alone gives) drawn over the true obstacles (what the simulator
knows), with each track's velocity and the rollout the planner chose.

`python benchmarks/tracking_figure.py` (also run by `make readme`) writes
docs/assets/tracking.png. The episode is deterministic, so the picture is too.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dynabarn.interfaces import EpisodeObserver
from dynabarn.protocol import get_protocol
from dynabarn.provenance import SHIPPED_WORLDS
from dynabarn.runner import EpisodeSpec, run_spec

ROOT = Path(__file__).resolve().parents[1]
FIGURE = ROOT / "docs" / "assets" / "tracking.png"
WORLD, SEED, AT = 205, 0, 3.0
"""A hard world of paper60, its first trial, and the moment drawn [s]."""


class _Snapshot(EpisodeObserver):
    """Keeps what the figure needs at the tick nearest `at` (an episode observer)."""

    def __init__(self, at: float) -> None:
        self.at = at
        self.tick = None

    def on_start(self, start) -> None:
        self.start = start

    def on_tick(self, tick) -> None:
        if self.tick is None and tick.time >= self.at:
            self.tick = tick

    def on_poses(self, times, poses) -> None:
        pass

    def on_end(self, result) -> None:
        self.result = result


def draw(path: Path = FIGURE) -> Path:
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Rectangle

    from dynabarn.files import save_atomically

    snap = _Snapshot(AT)
    world = SHIPPED_WORLDS / f"world_{WORLD:03d}.xml"
    run_spec(EpisodeSpec.make(world, "predictive", get_protocol("barn"), seed=SEED), observers=[snap])
    tick, info = snap.tick, snap.start.info
    fig = Figure(figsize=(7.2, 6.4), dpi=110)
    ax = fig.subplots()
    for cx, cy, sx, sy in info.walls:
        ax.add_patch(Rectangle((cx - sx / 2, cy - sy / 2), sx, sy, color="0.55"))
    x, y, yaw = tick.laser_pose
    angles = info.laser_angles + yaw
    hit = tick.scan < info.laser_range[1] - 1e-6
    ax.scatter(
        x + tick.scan[hit] * np.cos(angles[hit]), y + tick.scan[hit] * np.sin(angles[hit]), s=1.5, c="0.3", zorder=3
    )
    radii = [o.bounding_radius for o in snap.start.world.obstacles]
    for (ox, oy), r in zip(tick.obstacles, radii, strict=True):
        ax.add_patch(Circle((ox, oy), r, color="tab:red", alpha=0.35, lw=0, zorder=2))
    tracks = tick.tracks
    for tid, (tx, ty), (vx, vy), size in zip(
        tracks.ids, tracks.positions, tracks.velocities, tracks.sizes, strict=True
    ):
        ax.add_patch(Circle((tx, ty), size, fill=False, ec="tab:orange", lw=1.6, ls="--", zorder=4))
        ax.annotate("", (tx + vx, ty + vy), (tx, ty), arrowprops={"arrowstyle": "->", "color": "tab:orange", "lw": 1.4})
        ax.text(tx + 0.55, ty + 0.45, str(tid), color="tab:orange", fontsize=7, zorder=5)
    plan = tick.debug.get("local_plan")
    if plan is not None and len(plan):
        ax.plot(plan[:, 0], plan[:, 1], color="gold", lw=2.2, zorder=5, label="chosen rollout (2.4 s)")
    px, py, pyaw = tick.pose
    ax.add_patch(Circle((px, py), 0.33, color="tab:blue", zorder=6))
    ax.plot([px, px + 0.6 * np.cos(pyaw)], [py, py + 0.6 * np.sin(pyaw)], color="white", lw=2, zorder=7)
    ax.plot([], [], color="tab:red", alpha=0.35, lw=8, label="obstacles (truth)")
    ax.plot([], [], color="tab:orange", ls="--", label="tracks from the laser, velocity = 1 s of motion")
    ax.scatter([], [], s=4, c="0.3", label="laser returns")
    ax.set_xlim(-10.5, 11.5)
    ax.set_ylim(-10.5, 10.5)
    ax.set_aspect("equal")
    ax.legend(loc="lower left", fontsize=8, framealpha=0.9)
    recall = snap.result.tracking["recall"]
    ax.set_title(
        f"predictive on world_{WORLD:03d} (hard), seed {SEED}, t = {tick.time:.1f} s: "
        f"{len(tracks)} tracks; episode recall {recall:.2f}",
        fontsize=9,
    )
    fig.tight_layout()
    save_atomically(path, lambda f: fig.savefig(f, format="png", metadata={"Software": None}))
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=FIGURE, help=f"the PNG to write (default: {FIGURE})")
    args = parser.parse_args(argv)
    print(f"wrote {draw(args.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
