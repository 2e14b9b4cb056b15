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
| /world/static | foxglove.SceneUpdate (walls, goal, static cylinders) | once |
| /goal | foxglove.PoseInFrame | once |
| /world/obstacles | foxglove.SceneUpdate (cylinders and capsules as cylinders, boxes as cubes) | control rate |
| /scan | foxglove.LaserScan (frame `world`, pose = laser pose) | control rate |
| /robot/pose | foxglove.PoseInFrame (frame `world`) | pose rate (50 Hz) |
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

import foxglove
import numpy as np
from foxglove.mcap import MCAPWriteOptions
from foxglove.messages import LaserScan, PoseInFrame, SceneUpdate

from dynabarn import wire
from dynabarn.determinism import snap_array
from dynabarn.errors import DynabarnError
from dynabarn.metrics import EpisodeResult
from dynabarn.provenance import portable_path
from dynabarn.sim import EpisodeStart, Tick
from dynabarn.worlds.spec import Obstacle, WorldSpec

CHUNK_SIZE = 64 * 1024
WALL_CLOCK_FIELDS = ("rtf", "wall_time", "planner_ms_mean", "planner_ms_p95")
"""Result fields that depend on the machine's speed, kept out of recordings."""
MACHINE_FIELDS = (*WALL_CLOCK_FIELDS, "machine")
"""Result fields kept out of the recording's messages (the machine block goes into the
MCAP metadata record `dynabarn.machine`), so the messages are byte-identical across machines."""
MACHINE_METADATA = "dynabarn.machine"
DEBUG_RESOLUTION = 1e-4
"""[m] Planner debug geometry is recorded on this grid: DWA's and the oracle's rollouts use
numpy's sin and cos, whose last bits differ between CPUs."""
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


def _on_grid(value):
    """Float arrays on the debug grid (other values as they are)."""
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":
        return snap_array(value, DEBUG_RESOLUTION)
    return value


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

    # -- EpisodeObserver --------------------------------------------------------------
    def on_start(self, start: EpisodeStart) -> None:
        from dynabarn.robot import JACKAL

        self.path.parent.mkdir(parents=True, exist_ok=True)
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
        for topic in (*_JSON_SCHEMAS, *self.extra_channels):
            name, schema = _JSON_SCHEMAS.get(topic, (f"dynabarn{topic.replace('/', '.')}", {"type": "object"}))
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
        v, w = tick.command.tolist()
        raw_v, raw_w = tick.raw_command.tolist()
        self.log_json(TOPIC_CMD, t, {"v": v, "w": w, "raw_v": raw_v, "raw_w": raw_w})
        mv, mw = tick.velocity.tolist()
        self.log_json(
            TOPIC_METRICS,
            t,
            {"v": mv, "w": mw, "clearance": tick.clearance, "distance_to_goal": tick.distance_to_goal},
        )
        if tick.debug:
            self.log_json(TOPIC_DEBUG, t, {k: _on_grid(v) for k, v in tick.debug.items()})

    def on_poses(self, times: np.ndarray, poses: np.ndarray) -> None:
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
        body = json.dumps(_jsonable(payload), sort_keys=True, separators=(",", ":"), allow_nan=False)
        self._json[topic].log(body.encode(), log_time=_ns(t))

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def _metadata(self, start: EpisodeStart) -> dict:
        from dataclasses import asdict

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


def recorded_world(rec: Recording) -> WorldSpec:
    """The world the episode ran in, from the recording's metadata."""
    meta = rec.metadata
    if not meta or "world" not in meta or "keyframes" not in meta:
        raise DynabarnError(f"{rec.path}: no world metadata in this recording")
    world = meta["world"]
    try:
        keyframes = [np.asarray(meta["keyframes"][o["name"]]) for o in world["obstacles"]]
    except (KeyError, TypeError) as exc:
        raise DynabarnError(f"{rec.path}: malformed world metadata ({exc})") from None
    return WorldSpec.from_dict(world, keyframes)


def obstacle_track(rec: Recording, world: WorldSpec) -> tuple[np.ndarray, np.ndarray]:
    """What the obstacles did, as recorded: times (T,) [s] and centres (T, n, 2) [m].

    The recorder puts boxes in the update's cubes and the other obstacles in its
    cylinders, each in world order; this undoes that."""
    updates = rec.topic(TOPIC_OBSTACLES)
    n = len(world.obstacles)
    is_box = np.array([o.shape == "box" for o in world.obstacles], dtype=bool)
    times = np.array([t for t, _ in updates], dtype=np.float64)
    xy = np.zeros((len(updates), n, 2))
    for k, (_, m) in enumerate(updates):
        entity = m.entities[0] if m.entities else None
        cyl = [(c.pose.position.x, c.pose.position.y) for c in entity.cylinders] if entity else []
        cub = [(c.pose.position.x, c.pose.position.y) for c in entity.cubes] if entity else []
        if len(cyl) != n - is_box.sum() or len(cub) != is_box.sum():
            raise DynabarnError(f"{rec.path}: obstacle update at {times[k]:.2f} s does not match the world's obstacles")
        if n:
            xy[k, ~is_box] = np.asarray(cyl).reshape(-1, 2)
            xy[k, is_box] = np.asarray(cub).reshape(-1, 2)
    return times, xy


def _json_decoder_factory():
    from mcap.decoder import DecoderFactory

    class JsonDecoderFactory(DecoderFactory):
        def decoder_for(self, message_encoding: str, schema) -> Callable[[bytes], object] | None:
            if message_encoding == "json":
                return lambda data: json.loads(bytes(data))
            return None

    return JsonDecoderFactory()


def message_digest(path: Path | str) -> str:
    """sha256 over every message of a recording (topic, log time, bytes) in file order: the
    same on every machine for the same episode (the machine block is a metadata record,
    not a message). A file cut short raises DynabarnError."""
    import hashlib

    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for _schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
                h.update(channel.topic.encode())
                h.update(message.log_time.to_bytes(8, "little"))
                h.update(len(message.data).to_bytes(8, "little"))
                h.update(message.data)
    except (McapError, OSError) as exc:
        raise DynabarnError(f"{path}: cannot read the recording ({exc})") from None
    return h.hexdigest()


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
