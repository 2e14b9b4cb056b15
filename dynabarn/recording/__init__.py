"""Recordings: one MCAP file per episode (writer), read back (reader), one table of
topics (topics), their JSON schemas (schemas), what is drawn (scene), and the protobuf
wire encoding of foxglove messages (wire)."""

from dynabarn.recording.reader import (
    Recording,
    RecordingError,
    attached_world,
    laser_poses,
    message_digest,
    obstacle_track,
    pose_track,
    read_recording,
    recorded_world,
    returns,
    returns_in_world,
    scan_lasers,
)
from dynabarn.recording.scene import obstacle_pose
from dynabarn.recording.schemas import MACHINE_FIELDS, WALL_CLOCK_FIELDS
from dynabarn.recording.topics import TOPICS, Topic
from dynabarn.recording.writer import (
    EPISODE_METADATA,
    MACHINE_METADATA,
    RESULT_METADATA,
    WORLD_MEDIA_TYPE,
    McapRecorder,
    default_run_path,
)

__all__ = [
    "EPISODE_METADATA",
    "MACHINE_FIELDS",
    "MACHINE_METADATA",
    "RESULT_METADATA",
    "TOPICS",
    "WALL_CLOCK_FIELDS",
    "WORLD_MEDIA_TYPE",
    "McapRecorder",
    "Recording",
    "RecordingError",
    "Topic",
    "attached_world",
    "default_run_path",
    "laser_poses",
    "message_digest",
    "obstacle_pose",
    "obstacle_track",
    "pose_track",
    "read_recording",
    "recorded_world",
    "returns",
    "returns_in_world",
    "scan_lasers",
]


def __getattr__(name: str) -> str:
    """`TOPIC_SCAN` and the like, the topic names of earlier releases: from the table."""
    from dynabarn.recording import topics

    return getattr(topics, name)
