"""Reading MCAP recordings back, crash-tolerant: `read_recording`, the recorded world and
obstacle track, and `message_digest` (what the golden set compares)."""

from __future__ import annotations

import hashlib
import json
import math
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.metrics import OUTCOMES, numbers_ok
from dynabarn.recording.topics import METADATA, OBSTACLES, RESULT
from dynabarn.robot import JACKAL, mounted_pose
from dynabarn.worlds.spec import WorldSpec


@dataclass
class Recording:
    """A recording read back: messages per topic, in file order.

    Attributes:
        messages: topic -> list of (log_time [s], decoded message); JSON topics decode to
            dicts, foxglove topics to protobuf messages.
        schemas: topic -> schema name.
        truncated: True when the file ended early (a killed writer); `error` says how.
        attachments: name -> bytes of the file's attachments (the world's MJCF).
        records: name -> the MCAP metadata records (`dynabarn.episode`, `dynabarn.result`,
            `dynabarn.machine`), values as written (strings).
    """

    path: Path
    messages: dict[str, list[tuple[float, object]]] = field(default_factory=lambda: defaultdict(list))
    schemas: dict[str, str] = field(default_factory=dict)
    truncated: bool = False
    error: str = ""
    attachments: dict[str, bytes] = field(default_factory=dict)
    records: dict[str, dict[str, str]] = field(default_factory=dict)

    def topic(self, name: str) -> list[tuple[float, object]]:
        return self.messages.get(name, [])

    @property
    def metadata(self) -> dict | None:
        m = self.topic(METADATA.name)
        return m[0][1] if m else None  # type: ignore[return-value]

    @property
    def result(self) -> dict | None:
        m = self.topic(RESULT.name)
        return m[-1][1] if m else None  # type: ignore[return-value]

    def counts(self) -> dict[str, int]:
        return {k: len(v) for k, v in self.messages.items()}


class RecordingError(DynabarnError):
    """A file that is not a readable MCAP recording at all."""


def attached_world(rec: Recording) -> tuple[str, bytes] | None:
    """(file name, bytes) of the world file attached to the recording, checked against the
    hash its metadata records; None when the recording has none (older recordings)."""
    meta = rec.metadata or {}
    for name, data in rec.attachments.items():
        if not name.endswith(".xml"):
            continue
        if meta.get("world_sha256") and hashlib.sha256(data).hexdigest() != meta["world_sha256"]:
            raise DynabarnError(f"{rec.path}: the attached world {name} does not match the recorded world_sha256")
        return name, data
    return None


def recorded_world(rec: Recording) -> WorldSpec:
    """The world the episode ran in: its attached world file, else the recording's metadata."""
    attached = attached_world(rec)
    if attached is not None:
        from dynabarn.mjcf import read_world

        name, data = attached
        return read_world(rec.path.parent / name, data)
    meta = rec.metadata
    if not meta or "world" not in meta or "keyframes" not in meta:
        raise DynabarnError(f"{rec.path}: no world metadata in this recording")
    world = meta["world"]
    try:
        keyframes = [np.asarray(meta["keyframes"][o["name"]]) for o in world["obstacles"]]
    except (KeyError, TypeError) as exc:
        raise DynabarnError(f"{rec.path}: malformed world metadata ({exc})") from None
    return WorldSpec.from_dict(world, keyframes)


def pose_track(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """The robot's recorded poses: times (T,) [s] and (x, y, yaw) (T, 3), yaw unwrapped."""
    from dynabarn.recording.topics import POSE

    poses = rec.topic(POSE.name)
    if not poses:
        raise DynabarnError(f"{rec.path}: the recording holds no robot poses")
    t = np.array([p[0] for p in poses])
    xyyaw = np.array(
        [
            [m.pose.position.x, m.pose.position.y, 2 * math.atan2(m.pose.orientation.z, m.pose.orientation.w)]
            for _, m in poses
        ]
    )
    xyyaw[:, 2] = np.unwrap(xyyaw[:, 2])
    return t, xyyaw


def laser_poses(rec: Recording, times: np.ndarray) -> np.ndarray:
    """(x, y, yaw) of the laser in the world at `times` (K,): the robot's pose (interpolated
    between the 50 Hz poses) composed with the laser's mounting, as `/tf` says."""
    t, track = pose_track(rec)
    robot = np.column_stack([np.interp(times, t, track[:, k]) for k in range(3)])
    return mounted_pose(robot, ((rec.metadata or {}).get("robot", {}).get("laser_offset") or [0.0, 0.0]))


def scan_lasers(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """Times (S,) of the recorded scans and the laser's (x, y, yaw) (S, 3) at each: from
    the frame tree (the scan is in the `laser` frame), or for recordings from before it,
    the laser's world pose the scan itself carried."""
    from dynabarn.recording.topics import SCAN

    scans = rec.topic(SCAN.name)
    t = np.array([s[0] for s in scans], dtype=np.float64)
    if not scans:
        return t, np.zeros((0, 3))
    if scans[0][1].frame_id == "world":
        return t, np.array(
            [
                [m.pose.position.x, m.pose.position.y, 2 * math.atan2(m.pose.orientation.z, m.pose.orientation.w)]
                for _, m in scans
            ]
        )
    return t, laser_poses(rec, t)


def returns_in_world(ranges: np.ndarray, angles: np.ndarray, lasers: np.ndarray, range_max: float) -> list[np.ndarray]:
    """Per scan, its returns (m, 2) in the world: ranges (S, B) at beam angles (B,) in the
    laser's frame, cast from laser poses (S, 3); beams without a return left out."""
    ranges = np.atleast_2d(ranges)
    lasers = np.atleast_2d(lasers)
    hit = returns(ranges, range_max)
    heading = lasers[:, 2:3] + np.asarray(angles)[None, :]
    x = lasers[:, 0:1] + ranges * np.cos(heading)
    y = lasers[:, 1:2] + ranges * np.sin(heading)
    return [np.column_stack([x[k, hit[k]], y[k, hit[k]]]) for k in range(len(ranges))]


def returns(ranges: np.ndarray, range_max: float) -> np.ndarray:
    """Which beams hit something: a beam without a return reads `range_max` plus the
    laser's noise (clipped), so anything within five noise deviations of it is no return."""
    return np.asarray(ranges) < range_max - 5 * JACKAL.laser_noise_std


def obstacle_track(rec: Recording, world: WorldSpec) -> tuple[np.ndarray, np.ndarray]:
    """What the obstacles did, as recorded: times (T,) [s] and centres (T, n, 2) [m].

    The recorder puts boxes in the update's cubes and the other obstacles in its
    cylinders, each in world order; this undoes that."""
    updates = rec.topic(OBSTACLES.name)
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
        except Exception as exc:  # a cut or a corruption: mcap's, protobuf's, zstd's or lz4's error
            rec.truncated = True
            rec.error = f"{type(exc).__name__}: {exc}"
    rec.messages = dict(rec.messages)
    if rec.truncated and not rec.messages:
        raise RecordingError(f"{path}: corrupt or empty recording ({rec.error})")
    _check_messages(rec)
    rec.attachments, rec.records = _attachments_and_records(path)
    from dynabarn.world_file import check_world_data

    for name, data in rec.attachments.items():  # the attached world is a world file like any other
        if name.endswith(".xml"):
            check_world_data(path.parent / f"{path.name}:{name}", data)
    return rec


_METADATA_FIELDS = {"world": dict, "keyframes": dict, "robot": dict, "protocol": dict, "planner": str, "seed": int}
"""Fields of `/world/metadata` the readers use, with their JSON types (checked when present)."""


def _check_messages(rec: Recording) -> None:
    """The JSON messages every reader relies on have the shapes the writer gives them, or the
    file is refused in one line (a recording is someone else's file as often as ours)."""
    from dynabarn.recording.topics import TOPICS

    for topic in (t.name for t in TOPICS if t.encoding == "json"):
        for _, message in rec.messages.get(topic, []):
            if not isinstance(message, dict):
                raise RecordingError(f"{rec.path}: a {topic} message is {type(message).__name__}, not an object")
    meta = rec.metadata
    for key, kind in _METADATA_FIELDS.items():
        if meta is not None and key in meta and not (isinstance(meta[key], kind) and not isinstance(meta[key], bool)):
            raise RecordingError(f"{rec.path}: {METADATA.name} field {key!r} is not a JSON {kind.__name__}")
    _check_motion(rec)
    result = rec.result
    if result is not None and result.get("outcome") not in OUTCOMES:
        raise RecordingError(f"{rec.path}: the recorded result has no outcome the runner gives")
    if result is not None and not numbers_ok(result):
        raise RecordingError(f"{rec.path}: the recorded result has a metric that is not a number")


MAX_RECORDED_TIME = 2 * 3600.0
"""Latest log time a recording may hold [s]: two of the longest time limit (an hour), the
most an episode can last. A far-future time would make a video of billions of frames."""
MAX_RECORDED_COORDINATE = 1000.0
"""Largest |x| or |y| of a recorded pose [m] (keyframes are bounded alike)."""


def _check_motion(rec: Recording) -> None:
    """What the readers draw and replay from: every message's time within
    `MAX_RECORDED_TIME`, the robot's poses finite and within `MAX_RECORDED_COORDINATE`, and
    every scan with the first scan's number of beams and finite ranges."""
    from dynabarn.recording.topics import POSE, SCAN

    for topic, messages in rec.messages.items():
        if messages and not all(0.0 <= t <= MAX_RECORDED_TIME for t, _ in messages):
            raise RecordingError(f"{rec.path}: a {topic} message is logged outside [0, {MAX_RECORDED_TIME:g}] s")
    poses = [m.pose for _, m in rec.messages.get(POSE.name, []) if hasattr(m, "pose")]  # decoded ones
    if poses:
        xyzw = np.array([(p.position.x, p.position.y, p.orientation.z, p.orientation.w) for p in poses])
        if not np.isfinite(xyzw).all() or np.abs(xyzw[:, :2]).max() > MAX_RECORDED_COORDINATE:
            raise RecordingError(f"{rec.path}: a robot pose is not finite or lies beyond {MAX_RECORDED_COORDINATE:g} m")
    scans = [m.ranges for _, m in rec.messages.get(SCAN.name, []) if hasattr(m, "ranges")]
    if scans:
        if len({len(r) for r in scans}) != 1:
            raise RecordingError(f"{rec.path}: its scans have different numbers of beams")
        if not np.isfinite(np.array(scans, dtype=np.float64)).all():
            raise RecordingError(f"{rec.path}: a scan holds a range that is not finite")


def _attachments_and_records(path: Path) -> tuple[dict[str, bytes], dict[str, dict[str, str]]]:
    """The file's attachments and metadata records, from a record stream (so a file cut
    before its summary still gives those written before the cut). Chunks are skipped
    unread: attachments and metadata live outside them."""
    from mcap.records import Attachment, Metadata
    from mcap.stream_reader import StreamReader

    attachments: dict[str, bytes] = {}
    records: dict[str, dict[str, str]] = {}
    with path.open("rb") as f:
        try:
            for record in StreamReader(f, skip_magic=False, emit_chunks=True, validate_crcs=True).records:
                if isinstance(record, Attachment):
                    attachments[record.name] = bytes(record.data)
                elif isinstance(record, Metadata):
                    records[record.name] = dict(record.metadata)
        except Exception:  # a cut or a broken record: keep what came before it
            pass
    return attachments, records
