"""MCAP recordings of episodes: writing (an `EpisodeObserver`) and crash-tolerant reading.

Written with foxglove-sdk's built-in protobuf schemas, so files open in Foxglove as they
are; custom data travels on JSON channels with JSON schemas. Log time = simulated time
(nanoseconds from the episode start). Wall-clock measurements (planner compute time,
real-time factor) are left out, so the same world, planner, protocol and seed give a
byte-identical file on any machine. Chunks are small (64 KiB), so a killed process
loses only the last moments; `read_recording` recovers everything before a cut.

Topics (also in the README):

| topic | schema | rate |
|---|---|---|
| /world/metadata | JSON `dynabarn.EpisodeStart` | once |
| /world/static | foxglove.SceneUpdate (walls, goal) | once |
| /goal | foxglove.PoseInFrame | once |
| /world/obstacles | foxglove.SceneUpdate (cylinders) | control rate |
| /scan | foxglove.LaserScan (frame `world`, pose = laser pose) | control rate |
| /robot/pose | foxglove.PoseInFrame (frame `world`) | pose rate (100 Hz) |
| /cmd_vel | JSON `dynabarn.Command` | control rate |
| /metrics | JSON `dynabarn.StepMetrics` | control rate |
| /planner/debug | JSON `dynabarn.PlannerDebug` (e.g. local plan) | control rate, when the planner has any |
| /episode/result | JSON `dynabarn.EpisodeResult` | once, at the end |
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.metrics import EpisodeResult
from dynabarn.sim import EpisodeStart, Tick, portable_path

CHUNK_SIZE = 64 * 1024
WALL_CLOCK_FIELDS = ("rtf", "wall_time", "planner_ms_mean", "planner_ms_p95")
"""Result fields that depend on the machine, kept out of recordings."""
PROFILE = "dynabarn"

TOPIC_METADATA = "/world/metadata"
TOPIC_STATIC = "/world/static"
TOPIC_GOAL = "/goal"
TOPIC_OBSTACLES = "/world/obstacles"
TOPIC_SCAN = "/scan"
TOPIC_POSE = "/robot/pose"
TOPIC_CMD = "/cmd_vel"
TOPIC_METRICS = "/metrics"
TOPIC_DEBUG = "/planner/debug"
TOPIC_RESULT = "/episode/result"

_JSON_SCHEMAS = {
    TOPIC_METADATA: ("dynabarn.EpisodeStart", {"type": "object"}),
    TOPIC_CMD: (
        "dynabarn.Command",
        {
            "type": "object",
            "properties": {
                "v": {"type": "number", "description": "forward speed sent [m/s]"},
                "w": {"type": "number", "description": "yaw rate sent [rad/s]"},
                "raw_v": {"type": "number", "description": "planner output before limits [m/s]"},
                "raw_w": {"type": "number", "description": "planner output before limits [rad/s]"},
            },
        },
    ),
    TOPIC_METRICS: (
        "dynabarn.StepMetrics",
        {
            "type": "object",
            "properties": {
                "v": {"type": "number"},
                "w": {"type": "number"},
                "clearance": {"type": "number"},
                "distance_to_goal": {"type": "number"},
            },
        },
    ),
    TOPIC_DEBUG: ("dynabarn.PlannerDebug", {"type": "object"}),
    TOPIC_RESULT: ("dynabarn.EpisodeResult", {"type": "object"}),
}


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


class McapRecorder:
    """Records an episode to one MCAP file as it runs (an `EpisodeObserver`)."""

    def __init__(self, path: Path | str, *, chunk_size: int = CHUNK_SIZE, extra_channels: tuple[str, ...] = ()):
        self.path = Path(path)
        self.chunk_size = chunk_size
        self.extra_channels = extra_channels
        self._writer = None
        self._json: dict[str, object] = {}

    # -- EpisodeObserver --------------------------------------------------------------
    def on_start(self, start: EpisodeStart) -> None:
        import foxglove
        from foxglove.channels import LaserScanChannel, PoseInFrameChannel, SceneUpdateChannel
        from foxglove.mcap import MCAPWriteOptions

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._ctx = foxglove.Context()
        self._writer = foxglove.open_mcap(
            self.path,
            allow_overwrite=True,
            context=self._ctx,
            writer_options=MCAPWriteOptions(chunk_size=self.chunk_size, profile=PROFILE, compression_threads=0),
        )
        self._scan = LaserScanChannel(TOPIC_SCAN, context=self._ctx)
        self._pose = PoseInFrameChannel(TOPIC_POSE, context=self._ctx)
        self._goal = PoseInFrameChannel(TOPIC_GOAL, context=self._ctx)
        self._static = SceneUpdateChannel(TOPIC_STATIC, context=self._ctx)
        self._obstacles = SceneUpdateChannel(TOPIC_OBSTACLES, context=self._ctx)
        for topic in (*_JSON_SCHEMAS, *self.extra_channels):
            name, schema = _JSON_SCHEMAS.get(topic, (f"dynabarn{topic.replace('/', '.')}", {"type": "object"}))
            self._json[topic] = foxglove.Channel(
                topic,
                schema=foxglove.Schema(name=name, encoding="jsonschema", data=json.dumps(schema).encode()),
                message_encoding="json",
                context=self._ctx,
            )
        self._radii = np.array([o.radius for o in start.world.obstacles])
        self._heights = np.array([o.height for o in start.world.obstacles])
        self._names = [o.name for o in start.world.obstacles]
        self.log_json(TOPIC_METADATA, 0.0, self._metadata(start))
        self._log_static(start)

    def on_tick(self, tick: Tick) -> None:
        from foxglove.messages import LaserScan

        t = tick.time
        ns = _ns(t)
        lx, ly, lyaw = tick.laser_pose
        info_angles = self._angles
        self._scan.log(
            LaserScan(
                timestamp=self._stamp(t),
                frame_id="world",
                pose=self._pose_msg(lx, ly, self._laser_z, lyaw),
                start_angle=float(info_angles[0]),
                end_angle=float(info_angles[-1]),
                ranges=tick.scan.tolist(),
                intensities=[],
            ),
            log_time=ns,
        )
        self._log_obstacles(t, tick.obstacles)
        self.log_json(
            TOPIC_CMD,
            t,
            {
                "v": float(tick.command[0]),
                "w": float(tick.command[1]),
                "raw_v": float(tick.raw_command[0]),
                "raw_w": float(tick.raw_command[1]),
            },
        )
        self.log_json(
            TOPIC_METRICS,
            t,
            {
                "v": float(tick.velocity[0]),
                "w": float(tick.velocity[1]),
                "clearance": float(tick.clearance),
                "distance_to_goal": float(tick.distance_to_goal),
            },
        )
        if tick.debug:
            self.log_json(TOPIC_DEBUG, t, tick.debug)

    def on_poses(self, times: np.ndarray, poses: np.ndarray) -> None:
        from foxglove.messages import PoseInFrame

        for t, (x, y, yaw) in zip(times.tolist(), poses.tolist(), strict=True):
            self._pose.log(
                PoseInFrame(timestamp=self._stamp(t), frame_id="world", pose=self._pose_msg(x, y, 0.0, yaw)),
                log_time=_ns(t),
            )

    def on_end(self, result: EpisodeResult) -> None:
        if self._writer is None:
            return
        d = {k: v for k, v in result.to_dict().items() if k not in WALL_CLOCK_FIELDS}
        self.log_json(TOPIC_RESULT, result.sim_time, d)
        self.close()

    # -- helpers ------------------------------------------------------------------------
    def log_json(self, topic: str, t: float, payload: dict) -> None:
        channel = self._json[topic]
        channel.log(json.dumps(_jsonable(payload), sort_keys=True, separators=(",", ":")), log_time=_ns(t))

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def _metadata(self, start: EpisodeStart) -> dict:
        from dataclasses import asdict

        info = start.info
        self._angles = info.laser_angles
        from dynabarn.robot import JACKAL

        self._laser_z = JACKAL.laser_z
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
                "laser_angles": [float(info.laser_angles[0]), float(info.laser_angles[-1]), len(info.laser_angles)],
                "laser_range": list(info.laser_range),
                "laser_offset": info.laser_offset.tolist(),
                "laser_z": JACKAL.laser_z,
                "v_limits": list(info.v_limits),
                "w_max": info.w_max,
            },
            "keyframes": {
                o.name: np.column_stack([o.trajectory.times, o.trajectory.xy]) for o in start.world.obstacles
            },
        }

    @staticmethod
    def _stamp(t: float):
        from foxglove.messages import Timestamp

        ns = _ns(t)
        return Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)

    @staticmethod
    def _pose_msg(x: float, y: float, z: float, yaw: float):
        from foxglove.messages import Pose, Quaternion, Vector3

        return Pose(
            position=Vector3(x=float(x), y=float(y), z=float(z)),
            orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        )

    def _log_static(self, start: EpisodeStart) -> None:
        from foxglove.messages import (
            Color,
            CubePrimitive,
            CylinderPrimitive,
            PoseInFrame,
            SceneEntity,
            SceneUpdate,
            Vector3,
        )

        layout = start.world.layout
        cubes = [
            CubePrimitive(
                pose=self._pose_msg(w.centre[0], w.centre[1], w.size[2] / 2, 0.0),
                size=Vector3(x=w.size[0], y=w.size[1], z=w.size[2]),
                color=Color(r=0.55, g=0.55, b=0.6, a=1.0),
            )
            for w in layout.walls
        ]
        gx, gy = layout.goal
        goal = CylinderPrimitive(
            pose=self._pose_msg(gx, gy, 0.005, 0.0),
            size=Vector3(x=2 * start.protocol.goal_tolerance, y=2 * start.protocol.goal_tolerance, z=0.01),
            color=Color(r=0.1, g=0.8, b=0.2, a=0.5),
        )
        stamp = self._stamp(0.0)
        self._static.log(
            SceneUpdate(
                entities=[
                    SceneEntity(timestamp=stamp, frame_id="world", id="walls", cubes=cubes),
                    SceneEntity(timestamp=stamp, frame_id="world", id="goal", cylinders=[goal]),
                ]
            ),
            log_time=0,
        )
        self._goal.log(
            PoseInFrame(timestamp=stamp, frame_id="world", pose=self._pose_msg(gx, gy, 0.0, 0.0)), log_time=0
        )

    def _log_obstacles(self, t: float, xy: np.ndarray) -> None:
        from foxglove.messages import Color, CylinderPrimitive, SceneEntity, SceneUpdate, Vector3

        stamp = self._stamp(t)
        red = Color(r=0.85, g=0.15, b=0.12, a=1.0)
        cylinders = [
            CylinderPrimitive(pose=self._pose_msg(x, y, h / 2, 0.0), size=Vector3(x=2 * r, y=2 * r, z=h), color=red)
            for (x, y), r, h in zip(xy.tolist(), self._radii.tolist(), self._heights.tolist(), strict=True)
        ]
        self._obstacles.log(
            SceneUpdate(entities=[SceneEntity(timestamp=stamp, frame_id="world", id="obstacles", cylinders=cylinders)]),
            log_time=_ns(t),
        )


# -- reading --------------------------------------------------------------------------


@dataclass
class Recording:
    """A recording read back: messages per topic, in file order.

    Attributes:
        messages: topic -> list of (log_time [s], decoded message); JSON topics decode to
            dicts, foxglove topics to protobuf messages.
        schemas: topic -> schema name.
        truncated: True when the file ended early (a killed writer); `error` says how.
    """

    path: Path
    messages: dict[str, list[tuple[float, object]]] = field(default_factory=lambda: defaultdict(list))
    schemas: dict[str, str] = field(default_factory=dict)
    truncated: bool = False
    error: str = ""

    def topic(self, name: str) -> list[tuple[float, object]]:
        return self.messages.get(name, [])

    @property
    def metadata(self) -> dict | None:
        m = self.topic(TOPIC_METADATA)
        return m[0][1] if m else None  # type: ignore[return-value]

    @property
    def result(self) -> dict | None:
        m = self.topic(TOPIC_RESULT)
        return m[-1][1] if m else None  # type: ignore[return-value]

    def counts(self) -> dict[str, int]:
        return {k: len(v) for k, v in self.messages.items()}


class RecordingError(DynabarnError):
    """A file that is not a readable MCAP recording at all."""


def _json_decoder_factory():
    from mcap.decoder import DecoderFactory

    class JsonDecoderFactory(DecoderFactory):
        def decoder_for(self, message_encoding: str, schema) -> Callable[[bytes], object] | None:
            if message_encoding == "json":
                return lambda data: json.loads(bytes(data))
            return None

    return JsonDecoderFactory()


def read_recording(path: Path | str, *, decode: bool = True) -> Recording:
    """Read every message of an MCAP recording, recovering a truncated file up to its cut.

    Uses mcap's NonSeekingReader in file order (no summary section needed), so files
    whose writer was killed read back up to the last complete chunk.
    """
    from mcap.exceptions import McapError
    from mcap.reader import NonSeekingReader
    from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"recording not found: {path}")
    rec = Recording(path=path)
    with path.open("rb") as f:
        magic = f.read(8)
        if magic != b"\x89MCAP0\r\n":
            raise RecordingError(f"{path}: not an MCAP file")
        f.seek(0)
        reader = NonSeekingReader(
            f, validate_crcs=True, decoder_factories=[ProtobufDecoderFactory(), _json_decoder_factory()]
        )
        try:
            if decode:
                for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
                    rec.messages[channel.topic].append((message.log_time / 1e9, decoded))
                    if schema is not None:
                        rec.schemas.setdefault(channel.topic, schema.name)
            else:
                for schema, channel, message in reader.iter_messages(log_time_order=False):
                    rec.messages[channel.topic].append((message.log_time / 1e9, message.data))
                    if schema is not None:
                        rec.schemas.setdefault(channel.topic, schema.name)
        except (McapError, EOFError, ValueError, OSError, Exception) as exc:  # any cut or corruption
            rec.truncated = True
            rec.error = f"{type(exc).__name__}: {exc}"
    rec.messages = dict(rec.messages)
    if rec.truncated and not rec.messages:
        raise RecordingError(f"{path}: corrupt or empty recording ({rec.error})")
    return rec
