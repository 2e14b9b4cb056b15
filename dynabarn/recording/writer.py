"""Writing MCAP recordings of episodes as they run: `McapRecorder`, an `EpisodeObserver`.

Written with foxglove-sdk's built-in protobuf schemas, so files open in Foxglove as they
are; custom data travels on JSON channels with JSON schemas (the topics: `topics.TOPICS`).
Log time = simulated time (nanoseconds from the episode start). Wall-clock measurements
(planner compute time, real-time factor) are left out and the machine block is an MCAP
metadata record, so the same world, planner, protocol and seed give byte-identical
messages on any machine. Chunks are small (64 KiB), so a killed process loses only the
last moments; `reader.read_recording` recovers everything before a cut.
"""

from __future__ import annotations

import errno
import json
import math
import os
from dataclasses import asdict
from pathlib import Path

import foxglove
import numpy as np
from foxglove.mcap import MCAPWriteOptions
from foxglove.messages import LaserScan, PoseInFrame, SceneUpdate

from dynabarn.metrics import EpisodeResult
from dynabarn.provenance import portable_path
from dynabarn.recording import wire
from dynabarn.recording.topics import (
    TOPIC_GOAL,
    TOPIC_METADATA,
    TOPIC_OBSTACLES,
    TOPIC_POSE,
    TOPIC_RESULT,
    TOPIC_SCAN,
    TOPIC_STATIC,
    TOPICS,
)
from dynabarn.robot import JACKAL
from dynabarn.sim.events import EpisodeStart, Tick
from dynabarn.worlds.spec import Obstacle

CHUNK_SIZE = 64 * 1024
SPACE_RESERVE = 4 * 1024 * 1024
"""Free bytes below which a recording stops cleanly (MCAP's writer cannot recover from a
failed write: it would print one error per message and abort on close)."""
WALL_CLOCK_FIELDS = ("rtf", "wall_time", "planner_ms_mean", "planner_ms_p95")
"""Result fields that depend on the machine's speed, kept out of recordings."""
MACHINE_FIELDS = (*WALL_CLOCK_FIELDS, "machine")
"""Result fields kept out of the recording's messages (the machine block goes into the
MCAP metadata record `dynabarn.machine`), so the messages are byte-identical across machines."""
MACHINE_METADATA = "dynabarn.machine"
PROFILE = "dynabarn"
PER_TICK = tuple(t for t in TOPICS if t.per_tick is not None)


def _ns(t: float) -> int:
    return round(t * 1e9)


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return np.round(value, 6).tolist()
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, np.generic):
        return value.item()
    return value


def default_run_path(runs_dir: Path, world: str, planner: str, protocol: str, seed: int) -> Path:
    """runs/<world>_<planner>_<protocol>_s<seed>.mcap"""
    return Path(runs_dir) / f"{world}_{planner}_{protocol}_s{seed}.mcap"


SOURCES = {"teleop": "human", "oracle": "oracle"}
"""Planner name -> source of the demonstration (anything else: `planner`)."""

_WORLD_FRAME = wire.string(2, "world")
_OBSTACLE_COLOR = wire.color(0.85, 0.15, 0.12, 1.0)
_WALL_COLOR = wire.color(0.55, 0.55, 0.6, 1.0)
_GOAL_COLOR = wire.color(0.1, 0.8, 0.2, 0.5)


class McapRecorder:
    """Records an episode to one MCAP file as it runs (an `EpisodeObserver`).

    Args:
        path: the file to write (replaced if it exists).
        chunk_size: uncompressed chunk size [bytes]; small chunks bound what a killed
            process loses.
        extra_channels: further JSON topics a caller logs to with `log_json`.
        extra_metadata: fields added to `/world/metadata` (e.g. the operator's name).
    """

    def __init__(
        self,
        path: Path | str,
        *,
        chunk_size: int = CHUNK_SIZE,
        extra_channels: tuple[str, ...] = (),
        extra_metadata: dict | None = None,
    ):
        self.path = Path(path)
        self.chunk_size = chunk_size
        self.extra_channels = extra_channels
        self.extra_metadata = dict(extra_metadata or {})
        self._writer = None
        self._json: dict[str, foxglove.Channel] = {}
        self.stopped: str | None = None
        """Why the recording ended before the episode (a nearly full disk), or None."""

    # -- EpisodeObserver --------------------------------------------------------------
    def _space_left(self) -> int:
        st = os.statvfs(self.path.parent)
        return st.f_bavail * st.f_frsize

    def _room(self) -> bool:
        return self._space_left() >= SPACE_RESERVE + 2 * self.chunk_size

    def on_start(self, start: EpisodeStart) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.is_dir():
            raise IsADirectoryError(errno.EISDIR, f"{self.path} is a folder, not a recording file")
        if not self._room():
            raise OSError(errno.ENOSPC, f"no space left for a recording in {self.path.parent}")
        self._ctx = foxglove.Context()
        self._writer = foxglove.open_mcap(
            self.path,
            allow_overwrite=True,
            context=self._ctx,
            # compression_threads=0: compress on this thread, so one episode uses one core.
            writer_options=MCAPWriteOptions(chunk_size=self.chunk_size, profile=PROFILE, compression_threads=0),
        )

        def proto_channel(topic: str, message_type) -> foxglove.Channel:
            return foxglove.Channel(
                topic, schema=message_type.get_schema(), message_encoding="protobuf", context=self._ctx
            )

        self._scan = proto_channel(TOPIC_SCAN, LaserScan)
        self._pose = proto_channel(TOPIC_POSE, PoseInFrame)
        self._goal = proto_channel(TOPIC_GOAL, PoseInFrame)
        self._static = proto_channel(TOPIC_STATIC, SceneUpdate)
        self._obstacles = proto_channel(TOPIC_OBSTACLES, SceneUpdate)
        json_topics = [(t.name, t.schema, t.json_schema) for t in TOPICS if t.json_schema is not None]
        for topic in self.extra_channels:
            json_topics.append((topic, f"dynabarn{topic.replace('/', '.')}", {"type": "object"}))
        for topic, name, schema in json_topics:
            self._json[topic] = foxglove.Channel(
                topic,
                schema=foxglove.Schema(name=name, encoding="jsonschema", data=json.dumps(schema).encode()),
                message_encoding="json",
                context=self._ctx,
            )
        info = start.info
        self._start_angle = float(info.laser_angles[0])
        self._end_angle = float(info.laser_angles[-1])
        self._laser_z = JACKAL.laser_z
        obstacles = start.world.obstacles
        # The obstacle update is encoded once; each tick rewrites only the positions.
        # Boxes go in the entity's `cubes` (field 8), cylinders and capsules (drawn as
        # horizontal cylinders: SceneUpdate has no capsule) in its `cylinders` (field 10),
        # each in world order.
        boxes = [i for i, o in enumerate(obstacles) if o.shape == "box"]
        others = [i for i, o in enumerate(obstacles) if o.shape != "box"]
        primitives = []
        for field_number, encode, indices in ((8, wire.cube, boxes), (10, wire.cylinder, others)):
            for i in indices:
                z, q, size = _primitive_parts(obstacles[i])
                primitives.append((field_number, encode(wire.pose(0.0, 0.0, z, *q), size, _OBSTACLE_COLOR)))
        self._obstacle_block = wire.PrimitiveBlock(primitives)
        self._obstacle_order = np.array(boxes + others, dtype=np.int64)
        self.log_json(TOPIC_METADATA, 0.0, self._metadata(start))
        self._log_static(start)

    def on_tick(self, tick: Tick) -> None:
        if self._writer is None:
            return
        if not self._room():  # stop while the file can still be closed whole
            self.stopped = f"the disk was nearly full at {tick.time:.1f} s; the recording ends there"
            self.close()
            return
        t = tick.time
        ns = _ns(t)
        lx, ly, lyaw = tick.laser_pose.tolist()
        laser_pose = wire.pose(lx, ly, self._laser_z, 0.0, 0.0, math.sin(lyaw / 2), math.cos(lyaw / 2))
        self._scan.log(
            wire.laser_scan(ns, _WORLD_FRAME, laser_pose, self._start_angle, self._end_angle, tick.scan), log_time=ns
        )
        block = self._obstacle_block.encode(tick.obstacles[self._obstacle_order])
        entity = wire.scene_entity(ns, _WORLD_FRAME, "obstacles", primitives=block)
        self._obstacles.log(wire.scene_update([entity]), log_time=ns)
        for topic in PER_TICK:
            message = topic.per_tick(tick)
            if message is not None:
                self.log_json(topic.name, t, message)

    def on_poses(self, times: np.ndarray, poses: np.ndarray) -> None:
        if self._writer is None:
            return
        ns = np.round(times * 1e9).astype(np.int64).tolist()
        log = self._pose.log
        sin, cos = math.sin, math.cos  # libm, not numpy's CPU-dependent SIMD paths
        for n, x, y, yaw in zip(ns, poses[:, 0].tolist(), poses[:, 1].tolist(), poses[:, 2].tolist(), strict=True):
            half = yaw * 0.5
            log(wire.pose_in_frame(n, _WORLD_FRAME, wire.pose(x, y, 0.0, 0.0, 0.0, sin(half), cos(half))), log_time=n)

    def on_end(self, result: EpisodeResult) -> None:
        if self._writer is None:
            return
        d = result.to_dict()
        self._writer.write_metadata(
            MACHINE_METADATA, {k: json.dumps(v, sort_keys=True) for k, v in d.get("machine", {}).items()}
        )
        self.log_json(TOPIC_RESULT, result.sim_time, {k: v for k, v in d.items() if k not in MACHINE_FIELDS})
        self.close()

    # -- helpers ------------------------------------------------------------------------
    def log_json(self, topic: str, t: float, payload: dict) -> None:
        """Log a JSON message on one of the recorder's JSON topics at simulated time t [s]."""
        if self._writer is None:
            return
        body = json.dumps(_jsonable(payload), sort_keys=True, separators=(",", ":"), allow_nan=False)
        self._json[topic].log(body.encode(), log_time=_ns(t))

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def _metadata(self, start: EpisodeStart) -> dict:
        info = start.info
        return {
            "world": start.world.metadata(),
            "world_file": portable_path(start.world_path),
            "world_sha256": start.world_sha256,
            "protocol": start.protocol.to_dict(),
            "planner": start.planner,
            "planner_config": start.planner_config,
            "seed": start.seed,
            "clock_offset": start.clock_offset,
            "sim_config": asdict(start.config),
            "versions": start.versions,
            "robot": {
                "footprint": list(info.footprint),
                "laser_angles": [self._start_angle, self._end_angle, len(info.laser_angles)],
                "laser_range": list(info.laser_range),
                "laser_offset": info.laser_offset.tolist(),
                "laser_z": self._laser_z,
                "v_limits": list(info.v_limits),
                "w_max": info.w_max,
            },
            "keyframes": {
                o.name: np.column_stack([o.trajectory.times, o.trajectory.xy]) for o in start.world.obstacles
            },
            # Where the commands came from: a person, the privileged oracle (synthetic), a planner.
            "source": SOURCES.get(start.planner, "planner"),
            "synthetic": start.planner == "oracle",
            **self.extra_metadata,
        }

    def _log_static(self, start: EpisodeStart) -> None:
        layout = start.world.layout
        identity = (0.0, 0.0, 0.0, 1.0)
        cubes = [
            wire.cube(wire.pose(w.centre[0], w.centre[1], w.size[2] / 2, *identity), wire.vector3(*w.size), _WALL_COLOR)
            for w in layout.walls
        ]
        gx, gy = layout.goal
        d = 2 * start.protocol.goal_tolerance
        goal = wire.cylinder(wire.pose(gx, gy, 0.005, *identity), wire.vector3(d, d, 0.01), _GOAL_COLOR)
        entities = [
            wire.scene_entity(0, _WORLD_FRAME, "walls", cubes=cubes),
            wire.scene_entity(0, _WORLD_FRAME, "goal", cylinders=[goal]),
        ]
        if layout.cylinders:  # static BARN or mixed worlds
            static = [
                wire.cylinder(wire.pose(x, y, 0.5, *identity), wire.vector3(2 * r, 2 * r, 1.0), _WALL_COLOR)
                for x, y, r in layout.cylinders
            ]
            entities.append(wire.scene_entity(0, _WORLD_FRAME, "static_obstacles", cylinders=static))
        self._static.log(wire.scene_update(entities), log_time=0)
        self._goal.log(wire.pose_in_frame(0, _WORLD_FRAME, wire.pose(gx, gy, 0.0, *identity)), log_time=0)


def obstacle_pose(o: Obstacle) -> tuple[float, tuple[float, float, float, float]]:
    """Centre height and orientation quaternion (x, y, z, w) of an obstacle's primitive: a
    box turned by its yaw; a capsule's axis (a primitive's z) turned onto x (about y), then
    by its yaw (about z); a cylinder upright."""
    half = o.yaw / 2
    if o.shape == "box":
        return o.height / 2, (0.0, 0.0, math.sin(half), math.cos(half))
    if o.shape == "capsule":
        c = math.sqrt(0.5)
        return o.radius, (-c * math.sin(half), c * math.cos(half), c * math.sin(half), c * math.cos(half))
    return o.height / 2, (0.0, 0.0, 0.0, 1.0)


def _primitive_parts(o: Obstacle) -> tuple[float, tuple[float, float, float, float], bytes]:
    """`obstacle_pose` and the encoded size of the obstacle's SceneUpdate primitive (a
    capsule is drawn as a cylinder as long as the capsule)."""
    if o.shape == "box":
        size = wire.vector3(2 * o.half_length, 2 * o.half_width, o.height)
    elif o.shape == "capsule":
        size = wire.vector3(2 * o.radius, 2 * o.radius, 2 * (o.half_length + o.radius))
    else:
        size = wire.vector3(2 * o.radius, 2 * o.radius, o.height)
    return (*obstacle_pose(o), size)
