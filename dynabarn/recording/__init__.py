"""Recordings: one MCAP file per episode (writer), read back (reader), one table of
topics (topics), and the protobuf wire encoding of foxglove messages (wire)."""

from dynabarn.recording.reader import (
    Recording,
    RecordingError,
    message_digest,
    obstacle_track,
    read_recording,
    recorded_world,
)
from dynabarn.recording.topics import (
    TOPIC_CMD,
    TOPIC_DEBUG,
    TOPIC_GOAL,
    TOPIC_METADATA,
    TOPIC_METRICS,
    TOPIC_OBSTACLES,
    TOPIC_POSE,
    TOPIC_RESULT,
    TOPIC_SCAN,
    TOPIC_STATIC,
    TOPICS,
    Topic,
)
from dynabarn.recording.writer import (
    MACHINE_FIELDS,
    MACHINE_METADATA,
    WALL_CLOCK_FIELDS,
    McapRecorder,
    default_run_path,
    obstacle_pose,
)

__all__ = [
    "MACHINE_FIELDS",
    "MACHINE_METADATA",
    "TOPICS",
    "TOPIC_CMD",
    "TOPIC_DEBUG",
    "TOPIC_GOAL",
    "TOPIC_METADATA",
    "TOPIC_METRICS",
    "TOPIC_OBSTACLES",
    "TOPIC_POSE",
    "TOPIC_RESULT",
    "TOPIC_SCAN",
    "TOPIC_STATIC",
    "WALL_CLOCK_FIELDS",
    "McapRecorder",
    "Recording",
    "RecordingError",
    "Topic",
    "default_run_path",
    "message_digest",
    "obstacle_pose",
    "obstacle_track",
    "read_recording",
    "recorded_world",
]
