"""Streaming an episode to a rerun viewer as it runs: `RerunLive`, an `EpisodeObserver`.

The same entities and blueprint as `dynabarn-replay` (walls, goal, obstacles, robot, scan,
path, plans, the plotted metrics on `sim_time`), sent tick by tick instead of in bulk.
A viewer is spawned (rerun's native viewer; needs a display) or connected to (`--connect`:
a running `rerun`, `rerun --serve-web`, or `rerun --save FILE.rrd` with no window at all).
"""

from __future__ import annotations

import math

import numpy as np
import rerun as rr

from dynabarn.recording import returns
from dynabarn.recording.topics import plotted
from dynabarn.replay import (
    APP_ID,
    PATH_VERTICES,
    TIMELINE,
    blueprint,
    log_obstacles,
    log_static_world,
)

RUN = "runs/live"


class RerunLive:
    """Sends each tick to a rerun recording stream.

    Args:
        connect: a gRPC URL (`rerun+http://127.0.0.1:9876/proxy`) of a running viewer or
            server; None spawns rerun's native viewer.
    """

    def __init__(self, connect: str | None = None) -> None:
        self.stream = rr.RecordingStream(APP_ID, make_default=False, make_thread_default=False)
        if connect is None:
            self.stream.spawn()
        else:
            self.stream.connect_grpc(connect)
        self._path: list[tuple[float, float]] = []
        self.ticks = 0

    def on_start(self, start) -> None:
        s = self.stream
        self.world = start.world
        self.info = start.info
        meta = {"world": start.world.metadata(), "protocol": start.protocol.to_dict()}
        log_static_world(meta, s)
        length, width = start.info.footprint
        s.log(
            f"{RUN}/robot/body",
            rr.Boxes3D(half_sizes=[[length / 2, width / 2, 0.125]], centers=[[0, 0, 0.125]], fill_mode="solid"),
            static=True,
        )
        s.log(f"{RUN}/robot/heading", rr.Arrows3D(origins=[[0, 0, 0.26]], vectors=[[0.5, 0, 0]]), static=True)
        s.log(f"{RUN}/scan", rr.Points3D.from_fields(colors=[(230, 0, 230)], radii=[0.04]), static=True)
        s.log(
            "description",
            rr.TextDocument(
                f"# DynaBARN live\n\n{start.world.name}, planner `{start.planner}`, protocol "
                f"`{start.protocol.name}`, seed {start.seed}: running",
                media_type="text/markdown",
            ),
            static=True,
        )
        s.send_blueprint(blueprint([RUN]))

    def on_tick(self, tick) -> None:
        s = self.stream
        s.set_time(TIMELINE, duration=tick.time)
        x, y, yaw = tick.pose.tolist()
        lx, ly, _ = tick.laser_pose.tolist()
        r = tick.scan
        hit = returns(r, self.info.laser_range[1])
        a = self.info.laser_angles[hit] + yaw
        pts = np.column_stack([lx + r[hit] * np.cos(a), ly + r[hit] * np.sin(a), np.full(int(hit.sum()), 0.3)])
        s.log(f"{RUN}/scan", rr.Points3D(pts))
        log_obstacles(s, RUN, self.world, np.array([tick.time]), tick.obstacles[None], style=self.ticks == 0)
        self._path.append((x, y))
        path = np.asarray(self._path[:: max(1, len(self._path) // PATH_VERTICES)])
        s.log(f"{RUN}/robot_path", rr.LineStrips3D([np.column_stack([path, np.full(len(path), 0.02)])]))
        for key in ("local_plan", "global_plan"):
            plan = tick.debug.get(key)
            if plan is not None and len(plan) >= 2:
                p = np.asarray(plan)[:, :2]
                s.log(f"{RUN}/{key}", rr.LineStrips3D([np.column_stack([p, np.full(len(p), 0.05)])]))
        for topic, name in plotted():
            message = topic.per_tick(tick) if topic.per_tick is not None else None
            if message is not None and message.get(name) is not None and math.isfinite(message[name]):
                s.log(f"metrics/{name}/{RUN}", rr.Scalars(float(message[name])))
        self.ticks += 1

    def on_poses(self, times, poses) -> None:
        self.stream.send_columns(
            f"{RUN}/robot",
            indexes=[rr.TimeColumn(TIMELINE, duration=times)],
            columns=rr.Transform3D.columns(
                translation=np.column_stack([poses[:, :2], np.zeros(len(times))]),
                quaternion=np.column_stack(
                    [np.zeros(len(times)), np.zeros(len(times)), np.sin(poses[:, 2] / 2), np.cos(poses[:, 2] / 2)]
                ),
            ),
        )

    def on_end(self, result) -> None:
        self.stream.log(
            "description",
            rr.TextDocument(f"# DynaBARN live\n\n{result.summary()}", media_type="text/markdown"),
            static=True,
        )
        self.stream.flush()

    def close(self) -> None:
        self.stream.flush()
        self.stream.disconnect()
