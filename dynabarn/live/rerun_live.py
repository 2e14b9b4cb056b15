"""Streaming an episode to a rerun viewer as it runs: `RerunLive`, an `EpisodeObserver`.

The same entities and blueprint as `dynabarn-replay` (walls, goal, obstacles, robot, scan,
path, plans, the plotted metrics on `sim_time`), sent tick by tick instead of in bulk.
A viewer is spawned (rerun's native viewer; needs a display) or connected to (`--connect`:
a running `rerun`, `rerun --serve-web`, or `rerun --save FILE.rrd` with no window at all).
"""

from __future__ import annotations

import contextlib
import math
import subprocess

import numpy as np
import rerun as rr

from dynabarn.errors import EndEpisode
from dynabarn.interfaces.events import EpisodeObserver
from dynabarn.recording import returns_in_world
from dynabarn.recording.topic_registry import plotted
from dynabarn.rerun_replay import APP_ID, COLORS, PATH_VERTICES, blueprint
from dynabarn.rerun_scene import (
    TIMELINE,
    log_obstacles,
    log_robot_body,
    log_robot_poses,
    log_static_world,
    log_tracks,
)
from dynabarn.robot import JACKAL

RUN = "runs/live"
STREAM_CLOSED = (RuntimeError, ConnectionError, OSError)
"""What rerun-sdk raises when the viewer at the other end of the stream has gone."""


class RerunLive(EpisodeObserver):
    """Sends each tick to a rerun recording stream.

    Args:
        connect: a gRPC URL (`rerun+http://127.0.0.1:9876/proxy`) of a running viewer or
            server (`web_viewer.spawn_native_viewer` starts one on loopback).
        viewer: the viewer's process when we started it: the episode ends when it does
            (the window was closed), instead of streaming into nothing.
    """

    def __init__(self, connect: str, viewer: subprocess.Popen | None = None) -> None:
        self.stream = rr.RecordingStream(APP_ID, make_default=False, make_thread_default=False)
        self.stream.connect_grpc(connect)
        self.viewer = viewer
        self._path: list[tuple[float, float]] = []
        self.ticks = 0

    def on_start(self, start) -> None:
        s = self.stream
        self.world = start.world
        self.info = start.info
        meta = {"world": start.world.metadata(), "protocol": start.protocol.to_dict()}
        log_static_world(meta, s)
        log_robot_body(s, RUN, start.info.footprint, COLORS[0])
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
        if self.viewer is not None and self.viewer.poll() is not None:
            raise EndEpisode("the rerun viewer was closed")
        try:
            self._log_tick(tick)
        except STREAM_CLOSED as exc:  # the viewer's end of the stream went away between two checks
            raise EndEpisode(f"the rerun viewer was closed ({type(exc).__name__})") from None

    def _log_tick(self, tick) -> None:
        s = self.stream
        s.set_time(TIMELINE, duration=tick.time)
        x, y, _ = tick.pose.tolist()
        (xy,) = returns_in_world(tick.scan, self.info.laser_angles, tick.laser_pose, self.info.laser_range[1])
        s.log(f"{RUN}/scan", rr.Points3D(np.column_stack([xy, np.full(len(xy), JACKAL.laser_z)])))
        log_obstacles(s, RUN, self.world, np.array([tick.time]), tick.obstacles[None], style=self.ticks == 0)
        self._path.append((x, y))
        path = np.asarray(self._path[:: max(1, len(self._path) // PATH_VERTICES)])
        s.log(f"{RUN}/robot_path", rr.LineStrips3D([np.column_stack([path, np.full(len(path), 0.02)])]))
        for key in ("local_plan", "global_plan"):
            plan = tick.debug.get(key)
            if plan is not None and len(plan) >= 2:
                p = np.asarray(plan)[:, :2]
                s.log(f"{RUN}/{key}", rr.LineStrips3D([np.column_stack([p, np.full(len(p), 0.05)])]))
        tracks = tick.tracks
        if tracks is not None:
            times = np.array([tick.time])
            log_tracks(
                s, RUN, times, [len(tracks)], tracks.positions, tracks.sizes, tracks.velocities, style=self.ticks == 0
            )
        for topic, name in plotted():
            message = topic.per_tick(tick) if topic.per_tick is not None else None
            if message is not None and message.get(name) is not None and math.isfinite(message[name]):
                s.log(f"metrics/{name}/{RUN}", rr.Scalars(float(message[name])))
        self.ticks += 1

    def on_poses(self, times, poses) -> None:
        log_robot_poses(self.stream, RUN, times, poses[:, :2], poses[:, 2])

    def on_end(self, result) -> None:
        if self.viewer is not None and self.viewer.poll() is not None:
            return  # nobody to tell: the window was closed
        with contextlib.suppress(*STREAM_CLOSED):
            self.stream.log(
                "description",
                rr.TextDocument(f"# DynaBARN live\n\n{result.summary()}", media_type="text/markdown"),
                static=True,
            )
            self.stream.flush()

    def close(self) -> None:
        with contextlib.suppress(*STREAM_CLOSED):  # a viewer closed under us: nothing left to flush to
            self.stream.flush()
            self.stream.disconnect()
