"""Reading MCAP recordings back, crash-tolerant: `read_recording`, the recorded world and
obstacle track, and `message_digest` (what the golden set compares)."""

from __future__ import annotations

import hashlib
import json
import struct
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.recording.topics import TOPIC_METADATA, TOPIC_OBSTACLES, TOPIC_RESULT
from dynabarn.worlds.spec import WorldSpec


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
    from google.protobuf.message import DecodeError
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
        except (McapError, EOFError, ValueError, OSError, struct.error, DecodeError) as exc:  # a cut or corruption
            rec.truncated = True
            rec.error = f"{type(exc).__name__}: {exc}"
    rec.messages = dict(rec.messages)
    if rec.truncated and not rec.messages:
        raise RecordingError(f"{path}: corrupt or empty recording ({rec.error})")
    return rec
