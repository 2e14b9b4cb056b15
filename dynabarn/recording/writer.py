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

from dynabarn.files import check_target, claim_staging, file_name_part, is_same_file, publish, release
from dynabarn.interfaces.events import EpisodeObserver, EpisodeStart, Tick
from dynabarn.metrics import EpisodeResult, is_interrupted
from dynabarn.provenance import portable_path
from dynabarn.recording import scene, wire
from dynabarn.recording.schemas import MACHINE_FIELDS
from dynabarn.recording.topic_registry import recorded_topics
from dynabarn.recording.topics import (
    DEBUG,
    GOAL,
    METADATA,
    OBSTACLES,
    PLANS,
    POSE,
    RESULT,
    SCAN,
    STATIC,
    TF,
    TOPICS,
    TRACK_SCENE,
    TRACKS,
    Topic,
    tick_messages,
)
from dynabarn.robot import JACKAL

CHUNK_SIZE = 64 * 1024
SPACE_RESERVE = 4 * 1024 * 1024
"""Free bytes below which a recording stops cleanly (MCAP's writer cannot recover from a
failed write: it would print one error per message and abort on close)."""
MACHINE_METADATA = "dynabarn.machine"
EPISODE_METADATA = "dynabarn.episode"
RESULT_METADATA = "dynabarn.result"
"""MCAP metadata records: what `mcap info` and Foxglove show without reading the messages."""
PROFILE = "dynabarn"
LATCHED = tuple(t.name for t in TOPICS if t.latched)
"""Topics written once at the start: a live viewer that subscribes late is sent them again."""


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
    """runs/<world>_<planner>_<protocol>_s<seed>.mcap, each name made safe for a file name
    (`files.file_name_part`): whatever a world file or a plugin calls itself stays in `runs_dir`."""
    parts = "_".join(file_name_part(n) for n in (world, planner, protocol))
    return Path(runs_dir) / f"{parts}_s{int(seed)}.mcap"


SOURCES = {"teleop": "human", "oracle": "oracle"}
"""Planner name -> source of the demonstration (anything else: `planner`)."""


class _Fanout:
    """One topic's channels, one per foxglove context (the file's, a live server's)."""

    __slots__ = ("channels",)

    def __init__(self, channels: list[foxglove.Channel]) -> None:
        self.channels = channels

    def log(self, data: bytes, log_time: int) -> None:
        for c in self.channels:
            c.log(data, log_time=log_time)


class McapRecorder(EpisodeObserver):
    """Records an episode to one MCAP file as it runs (an `EpisodeObserver`).

    Args:
        path: the file to write (replaced if it exists); None: no file (a live view only).
        chunk_size: uncompressed chunk size [bytes]; small chunks bound what a killed
            process loses.
        extra_channels: further JSON topics (`Topic`s with a schema) a caller logs to with
            `log_json`.
        extra_metadata: fields added to `/world/metadata` (e.g. the operator's name).
        live: further foxglove contexts every message is sent to as well (a live server's),
            under the same topics and schemas.
        claim: claim the staging file here (`files.claim_staging`: created exclusively,
            locked while the episode runs); False where the caller holds the claim (the
            writer process, whose episode's process claimed it).
    """

    def __init__(
        self,
        path: Path | str | None,
        *,
        chunk_size: int = CHUNK_SIZE,
        extra_channels: tuple[Topic, ...] = (),
        extra_metadata: dict | None = None,
        live: tuple[foxglove.Context, ...] = (),
        claim: bool = True,
    ):
        self.path = Path(path) if path is not None else None
        self.staging = staging_path(self.path) if self.path is not None else None
        """Where the recording is written as it runs; renamed to `path` when it is closed, so an
        existing recording is replaced only by a whole one and a killed process leaves its
        readable start here, never under the final name."""
        self.chunk_size = chunk_size
        self.extra_channels = extra_channels
        self.extra_metadata = dict(extra_metadata or {})
        self.live = live
        self._writer = None
        self._open = False
        self._json: dict[str, _Fanout | foxglove.Channel] = {}
        self._by_context: dict[int, dict[str, foxglove.Channel]] = {}
        """id(context) -> topic -> channel (the live server resends latched messages on it)."""
        self.latched: dict[str, list[tuple[bytes, int]]] = {}
        """What was written on the LATCHED topics: (message, log time [ns])."""
        self.stopped: str | None = None
        """Why the recording ended before the episode (a nearly full disk, a topic that raised), or None."""
        self.claim = claim
        self._claim: int | None = None
        self.kept: Path | None = None
        """Where the finished recording is: `path`, or beside it (`NAME.interrupted.mcap`)
        for an interrupted episode when a recording was at `path` already."""

    # -- EpisodeObserver --------------------------------------------------------------
    def _space_left(self) -> int:
        st = os.statvfs(self.path.parent)
        return st.f_bavail * st.f_frsize

    def _room(self) -> bool:
        return self.path is None or self._space_left() >= SPACE_RESERVE + 2 * self.chunk_size

    def check_can_open(self) -> None:
        """The file's folder made; an OSError if the file cannot be written there (a folder
        in its place, a nearly full disk)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.is_dir():
            raise IsADirectoryError(errno.EISDIR, f"{self.path} is a folder, not a recording file")
        check_target(self.path)  # a device or FIFO is never replaced by a recording
        if not self._room():
            raise OSError(errno.ENOSPC, f"no space left for a recording in {self.path.parent}")

    def hold(self, claim: int) -> None:
        """Take over a claim on the staging file made by the caller (`files.claim_staging`);
        it is released when the recording is closed."""
        self._claim = claim

    def _open_file(self, start: EpisodeStart) -> foxglove.Context:
        self.check_can_open()
        if self.claim and self._claim is None:
            self._claim = claim_staging(self.staging, self.path)
        ctx = foxglove.Context()
        self._writer = foxglove.open_mcap(
            self.staging,
            allow_overwrite=True,
            context=ctx,
            # compression_threads=0: compress on this thread, so one episode uses one core.
            writer_options=MCAPWriteOptions(chunk_size=self.chunk_size, profile=PROFILE, compression_threads=0),
        )
        if self._claim is not None and not is_same_file(self.staging, self._claim):
            self._writer.close()
            self._writer = None
            raise OSError(errno.EPERM, "the staging file was replaced as it was opened; not written", str(self.staging))
        # The world file itself, so the recording rebuilds its world without the project
        # (create and log time 0: the same bytes on every machine).
        if start.world_xml:
            self._writer.attach(
                log_time=0, create_time=0, name=start.world_path.name, media_type=WORLD_MEDIA_TYPE, data=start.world_xml
            )
        self._writer.write_metadata(EPISODE_METADATA, _strings(_episode_record(start)))
        return ctx

    def on_start(self, start: EpisodeStart) -> None:
        contexts = [self._open_file(start)] if self.path is not None else []
        contexts += list(self.live)
        self._contexts = contexts  # a context dropped closes its channels
        self._open = True

        self._by_context = {id(c): {} for c in contexts}

        def fanout(topic: str, schema: foxglove.Schema, encoding: str) -> _Fanout | foxglove.Channel:
            channels = []
            for c in contexts:
                channel = foxglove.Channel(topic, schema=schema, message_encoding=encoding, context=c)
                self._by_context[id(c)][topic] = channel
                channels.append(channel)
            # One context (the usual file-only case): the channel itself, no call in between.
            return channels[0] if len(channels) == 1 else _Fanout(channels)

        # Every topic of the table, in its order: protobuf ones with their foxglove schema.
        channels = {}
        topics = (*recorded_topics(), *self.extra_channels)  # the table, installed and registered ones
        self._per_tick = [t for t in topics if t.per_tick is not None]
        for t in topics:
            if t.message_type is not None:
                schema = t.message_type.get_schema()
            else:
                schema = foxglove.Schema(
                    name=t.schema, encoding="jsonschema", data=json.dumps(t.schema_document).encode()
                )
            channels[t.name] = fanout(t.name, schema, t.encoding)
        self._json = {t.name: channels[t.name] for t in topics if t.json_schema is not None}
        self._scan, self._tf, self._pose = channels[SCAN.name], channels[TF.name], channels[POSE.name]
        self._goal, self._static, self._obstacles = channels[GOAL.name], channels[STATIC.name], channels[OBSTACLES.name]
        self._plans, self._track_scene = channels[PLANS.name], channels[TRACK_SCENE.name]
        info = start.info
        self._start_angle = float(info.laser_angles[0])
        self._end_angle = float(info.laser_angles[-1])
        self._laser_z = JACKAL.laser_z
        self._frames = scene.FrameTree(float(info.laser_offset[0]), float(info.laser_offset[1]), self._laser_z)
        self._obstacle_block, self._obstacle_order = scene.obstacle_block(start.world.obstacles)
        self.log_json(METADATA.name, 0.0, self._metadata(start))
        static_update, goal_pose = scene.static_scene(start.world, start.protocol.goal_tolerance)
        self._log(self._static, STATIC.name, static_update, 0)
        self._log(self._goal, GOAL.name, goal_pose, 0)

    def on_tick(self, tick: Tick) -> None:
        if not self._open:
            return
        if not self._room():  # stop while the file can still be closed whole
            self.stopped = f"the disk was nearly full at {tick.time:.1f} s; the recording ends there"
            self.close()
            return
        t = tick.time
        ns = _ns(t)
        self._scan.log(
            wire.laser_scan(ns, scene.LASER_FRAME, scene.IDENTITY_POSE, self._start_angle, self._end_angle, tick.scan),
            log_time=ns,
        )
        block = self._obstacle_block.encode(tick.obstacles[self._obstacle_order])
        entity = wire.scene_entity(ns, scene.WORLD_FRAME, "obstacles", primitives=block)
        self._obstacles.log(wire.scene_update([entity]), log_time=ns)
        messages, self.stopped = tick_messages(self._per_tick, tick)
        for topic, message in messages:
            self.log_json(topic.name, t, message)
            if topic.name == DEBUG.name:
                self._plans.log(scene.plans_update(ns, message), log_time=ns)
            elif topic.name == TRACKS.name:
                self._track_scene.log(scene.tracks_update(ns, message), log_time=ns)
        if self.stopped:  # an installed topic's bug: the recording ends whole, and says why
            self.close()

    def on_poses(self, times: np.ndarray, poses: np.ndarray) -> None:
        if not self._open:
            return
        ns = np.round(times * 1e9).astype(np.int64).tolist()
        log_pose, log_tf, tf_message = self._pose.log, self._tf.log, self._frames.message
        world = scene.WORLD_FRAME
        sin, cos = math.sin, math.cos  # libm, not numpy's CPU-dependent SIMD paths
        for n, x, y, yaw in zip(ns, poses[:, 0].tolist(), poses[:, 1].tolist(), poses[:, 2].tolist(), strict=True):
            half = yaw * 0.5
            qz, qw = sin(half), cos(half)
            log_pose(wire.pose_in_frame(n, world, wire.pose(x, y, 0.0, 0.0, 0.0, qz, qw)), log_time=n)
            log_tf(tf_message(n, x, y, qz, qw), log_time=n)

    def on_end(self, result: EpisodeResult) -> None:
        if not self._open:
            return
        d = result.to_dict()
        judged = {k: v for k, v in d.items() if k not in MACHINE_FIELDS}
        if self._writer is not None:
            self._writer.write_metadata(MACHINE_METADATA, _strings(d.get("machine", {})))
            self._writer.write_metadata(RESULT_METADATA, _strings(judged))
        self.log_json(RESULT.name, result.sim_time, judged)
        # An interrupted episode never replaces a finished recording (kept beside it instead).
        self.close(replace=not is_interrupted(result))

    # -- helpers ------------------------------------------------------------------------
    def log_json(self, topic: str, t: float, payload: dict) -> None:
        """Log a JSON message on one of the recorder's JSON topics at simulated time t [s]."""
        if not self._open:
            return
        body = json.dumps(_jsonable(payload), sort_keys=True, separators=(",", ":"), allow_nan=False).encode()
        self._log(self._json[topic], topic, body, _ns(t))

    def _log(self, channel, topic: str, data: bytes, ns: int) -> None:
        """Log one message; those of the topics written once (LATCHED) are kept for late subscribers."""
        if topic in LATCHED:
            self.latched.setdefault(topic, []).append((data, ns))
        channel.log(data, log_time=ns)

    def live_channels(self, context: foxglove.Context) -> dict[str, foxglove.Channel]:
        """topic -> this recorder's channel in one of its live contexts (empty before the start)."""
        return dict(self._by_context.get(id(context), {}))

    def abandon(self) -> None:
        """Close what was written into NAME.part and leave it there, not renamed (the
        episode's process is gone: the file never looks finished)."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def close(self, *, replace: bool = True) -> None:
        """End the recording: the file is closed, made durable and renamed to `path` (with
        `replace=False`, beside a recording already there: `files.publish`)."""
        self._open = False
        try:
            if self._writer is not None:
                self._writer.close()
                self._writer = None
                with open(self.staging, "rb") as f:
                    os.fsync(f.fileno())
                self.kept = publish(self.staging, self.path, replace=replace)
        finally:
            release(self._claim)
            self._claim = None

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


def staging_path(path: Path) -> Path:
    """Where a recording to `path` is written while its episode runs (`NAME.mcap.part`)."""
    return path.with_name(f"{path.name}.part")


WORLD_MEDIA_TYPE = "application/vnd.mujoco.mjcf+xml"
"""Media type of the attached world file (MJCF is XML)."""


def _strings(record: dict) -> dict[str, str]:
    """An MCAP metadata record: strings as they are, everything else as compact JSON."""
    return {
        k: v if isinstance(v, str) else json.dumps(_jsonable(v), sort_keys=True, separators=(",", ":"))
        for k, v in record.items()
    }


def _episode_record(start: EpisodeStart) -> dict:
    """The `dynabarn.episode` metadata record: which episode this is, in a few fields."""
    return {
        "world": start.world.name,
        "world_file": start.world_path.name,
        "world_sha256": start.world_sha256,
        "planner": start.planner,
        "protocol": start.protocol.name,
        "seed": start.seed,
        "clock_offset": start.clock_offset,
        "versions": start.versions,
    }
