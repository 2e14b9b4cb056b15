"""The one table of recording topics: name, schema, rate, what it holds, how it is made.

Everything else follows this table: the recorder opens a channel per topic and writes the
per-tick JSON topics from it, `dynabarn-replay` plots the fields a topic names in `plots`,
and docs/concepts/recordings.md's topic table is `markdown_table()` (a test compares them).

A new JSON topic computed from each control tick is one `Topic` here with a `per_tick`
function (return None to skip a tick); docs/architecture.md, "Extending", walks through one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from foxglove.messages import FrameTransforms, LaserScan, PoseInFrame, SceneUpdate

from dynabarn.determinism import snap_array
from dynabarn.interfaces.events import Tick
from dynabarn.recording.schemas import (
    DEBUG_SCHEMA,
    METADATA_SCHEMA,
    TRACKS_SCHEMA,
    document,
    nullable_number,
    number,
    obj,
    result_schema,
)

DEBUG_RESOLUTION = 1e-4
"""[m] Planner debug geometry is recorded on this grid: DWA's and the oracle's rollouts use
numpy's sin and cos, whose last bits differ between CPUs."""


@dataclass(frozen=True, slots=True)
class Topic:
    """One recorded topic.

    Attributes:
        name: the MCAP topic, e.g. `/cmd_vel`.
        schema: the schema name (`foxglove.*` protobuf, or `dynabarn.*` JSON).
        rate: when it is written, for people (`once`, `10 Hz`, ...).
        doc: what a message holds.
        json_schema: the JSON schema of a JSON topic (None: a foxglove protobuf topic,
            written by the recorder itself).
        per_tick: for JSON topics written every control tick, the message of a tick
            (None: nothing this tick).
        plots: fields `dynabarn-replay` draws as time series (under `metrics/<field>`).
        message_type: a protobuf topic's foxglove message class (its schema comes from it).
        latched: written once at the start and sent again to late live subscribers.
        in_3d: shown in the Foxglove layout's 3D panel.
    """

    name: str
    schema: str
    rate: str
    doc: str
    json_schema: dict | None = None
    per_tick: Callable[[Tick], dict | None] | None = None
    plots: tuple[str, ...] = ()
    message_type: Any = None
    latched: bool = False
    in_3d: bool = False

    @property
    def encoding(self) -> str:
        return "protobuf" if self.json_schema is None else "json"

    @property
    def schema_document(self) -> dict | None:
        """The JSON schema as written to the file: the dialect, and the schema name as its title."""
        return None if self.json_schema is None else document(self.schema, self.json_schema)


def _command(tick: Tick) -> dict:
    v, w = tick.command.tolist()
    raw_v, raw_w = tick.raw_command.tolist()
    return {"v": v, "w": w, "raw_v": raw_v, "raw_w": raw_w}


def _step_metrics(tick: Tick) -> dict:
    v, w = tick.velocity.tolist()
    return {"v": v, "w": w, "clearance": tick.clearance, "distance_to_goal": tick.distance_to_goal}


def _on_grid(value):
    """Float arrays on the debug grid (other values as they are)."""
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":
        return snap_array(value, DEBUG_RESOLUTION)
    return value


GLOBAL_PLAN_POINTS = 200
"""A recorded global plan is thinned to at most this many points (the first and last kept)."""


def thin(points: np.ndarray, most: int) -> np.ndarray:
    """At most `most` of the points, evenly spread, the first and last included."""
    if len(points) <= most:
        return points
    return points[np.unique(np.linspace(0, len(points) - 1, most).astype(np.int64))]


def _planner_debug(tick: Tick) -> dict | None:
    if not tick.debug:
        return None
    debug = {k: _on_grid(v) for k, v in tick.debug.items()}
    if isinstance(debug.get("global_plan"), np.ndarray):
        debug["global_plan"] = thin(debug["global_plan"], GLOBAL_PLAN_POINTS)
    return debug


def _tracks(tick: Tick) -> dict | None:
    tracks = tick.tracks
    if tracks is None:
        return None
    return {
        "ids": tracks.ids.tolist(),
        "positions": snap_array(tracks.positions, DEBUG_RESOLUTION).tolist(),
        "velocities": snap_array(tracks.velocities, DEBUG_RESOLUTION).tolist(),
        "sizes": snap_array(tracks.sizes, DEBUG_RESOLUTION).tolist(),
        "position_std": snap_array(np.sqrt(tracks.position_var.max(axis=1)), DEBUG_RESOLUTION).tolist(),
        "age": snap_array(tracks.age, DEBUG_RESOLUTION).tolist(),
        "last_seen": snap_array(tracks.last_seen, DEBUG_RESOLUTION).tolist(),
    }


METADATA = Topic(
    "/world/metadata",
    "dynabarn.EpisodeStart",
    "once",
    "world, keyframes, protocol, planner and config, seed, clock offset, versions (dynabarn, mujoco, "
    "numpy, scipy; torch for bc/td3)",
    json_schema=METADATA_SCHEMA,
    latched=True,
)
STATIC = Topic(
    "/world/static",
    "foxglove.SceneUpdate",
    "once",
    "walls (cubes), goal region (cylinder), static cylinders (entity `static_obstacles`, when the world has any)",
    message_type=SceneUpdate,
    latched=True,
    in_3d=True,
)
GOAL = Topic(
    "/goal",
    "foxglove.PoseInFrame",
    "once",
    "the goal, frame `world`",
    message_type=PoseInFrame,
    latched=True,
    in_3d=True,
)
OBSTACLES = Topic(
    "/world/obstacles",
    "foxglove.SceneUpdate",
    "10 Hz",
    "cylinders for the cylinder and capsule obstacles (a capsule as a horizontal cylinder along its axis), "
    "cubes for the boxes, each list in world order; `dynabarn.recording.obstacle_track` undoes it",
    message_type=SceneUpdate,
    in_3d=True,
)
SCAN = Topic(
    "/scan",
    "foxglove.LaserScan",
    "10 Hz",
    "frame `laser` (placed by `/tf`), pose = identity",
    message_type=LaserScan,
    in_3d=True,
)
TF = Topic(
    "/tf",
    "foxglove.FrameTransforms",
    "50 Hz",
    "the frame tree `world -> odom -> base_link -> laser` in every message (odom = world: the pose is the "
    "simulator's, without drift)",
    message_type=FrameTransforms,
)
POSE = Topic("/robot/pose", "foxglove.PoseInFrame", "50 Hz", "frame `world`", message_type=PoseInFrame)
CMD = Topic(
    "/cmd_vel",
    "dynabarn.Command",
    "10 Hz",
    "v, w sent; raw_v, raw_w from the planner (on the 1 um/s command grid)",
    json_schema=obj(
        "the command of one control tick",
        {
            "v": number("forward speed sent [m/s]"),
            "w": number("yaw rate sent [rad/s]"),
            "raw_v": number("planner output before limits [m/s]"),
            "raw_w": number("planner output before limits [rad/s]"),
        },
        ("v", "w", "raw_v", "raw_w"),
        closed=True,
    ),
    per_tick=_command,
    plots=("v", "w"),
)
METRICS = Topic(
    "/metrics",
    "dynabarn.StepMetrics",
    "10 Hz",
    "measured v, w, clearance, distance to goal",
    json_schema=obj(
        "what was measured at one control tick",
        {
            "v": number("measured forward speed [m/s]"),
            "w": number("measured yaw rate [rad/s]"),
            "clearance": nullable_number("footprint to the nearest obstacle's surface [m] (null: no obstacles)"),
            "distance_to_goal": number("robot centre to the goal [m]"),
        },
        ("v", "w", "clearance", "distance_to_goal"),
        closed=True,
    ),
    per_tick=_step_metrics,
    plots=("clearance", "distance_to_goal"),
)
DEBUG = Topic(
    "/planner/debug",
    "dynabarn.PlannerDebug",
    "10 Hz",
    "e.g. local and global plans, on a 0.1 mm grid, when the planner has any (drawn on `/planner/plans`)",
    json_schema=DEBUG_SCHEMA,
    per_tick=_planner_debug,
)
PLANS = Topic(
    "/planner/plans",
    "foxglove.SceneUpdate",
    "10 Hz",
    "the local plan (entity `local_plan`, yellow) and the global plan (`global_plan`, blue) as line strips, "
    "frame `world`, when the planner has them",
    message_type=SceneUpdate,
    in_3d=True,
)
TRACKS = Topic(
    "/perception/tracks",
    "dynabarn.Tracks",
    "10 Hz",
    "the planner's tracked obstacles (ids, centres, velocities, sizes, uncertainty, age), beside the true "
    "`/world/obstacles`, when the planner tracks them (drawn on `/perception/tracks/scene`)",
    json_schema=TRACKS_SCHEMA,
    per_tick=_tracks,
)
TRACK_SCENE = Topic(
    "/perception/tracks/scene",
    "foxglove.SceneUpdate",
    "10 Hz",
    "each track as a translucent cylinder of its size (entity `tracks`) and its velocity as a line to where "
    "it will be in 1 s (entity `track_velocities`), frame `world`",
    message_type=SceneUpdate,
    in_3d=True,
)
RESULT = Topic(
    "/episode/result",
    "dynabarn.EpisodeResult",
    "once, at the end",
    "the metrics, without wall-clock fields",
    json_schema=result_schema(),
)

TOPICS: tuple[Topic, ...] = (
    METADATA,
    STATIC,
    GOAL,
    OBSTACLES,
    SCAN,
    TF,
    POSE,
    CMD,
    METRICS,
    DEBUG,
    PLANS,
    TRACKS,
    TRACK_SCENE,
    RESULT,
)
"""Every topic, in the documentation's order; per-tick JSON topics are written in this order."""


def __getattr__(name: str) -> str:
    """`TOPIC_SCAN` is `SCAN.name` (the names earlier releases exported): the table's entry."""
    topic = globals().get(name.removeprefix("TOPIC_")) if name.startswith("TOPIC_") else None
    if isinstance(topic, Topic):
        return topic.name
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


FRAMES = ("world", "odom", "base_link", "laser")
"""The frame tree on `/tf`, root first: each frame is the child of the one before."""


TOPIC_RAISED = "recording topic"
"""How a recording stopped by a topic that raised begins its reason (`McapRecorder.stopped`):
`dynabarn-run` then exits non-zero, since what was asked to be recorded is not."""


def stopped_by_a_topic(reason: object) -> bool:
    """Whether a recording's `stopped` reason is a topic that raised (not a full disk)."""
    return isinstance(reason, str) and reason.startswith(TOPIC_RAISED)


def tick_messages(topics: Sequence[Topic], tick: Tick) -> tuple[list[tuple[Topic, dict]], str | None]:
    """Each per-tick topic's message of `tick` (those that have one), up to a topic that
    raises: then also why the recording stops there (`TOPIC_RAISED` ...), else None."""
    messages = []
    for topic in topics:
        try:
            message = topic.per_tick(tick)
        except Exception as exc:  # an installed topic's bug, never the episode's end
            why = f"{type(exc).__name__}: {str(exc)[:200]}"
            return messages, f"{TOPIC_RAISED} {topic.name} raised {why}; the recording ends at {tick.time:.1f} s"
        if message is not None:
            messages.append((topic, message))
    return messages, None


def markdown_table() -> str:
    """The topic table of docs/concepts/recordings.md."""
    rows = ["| topic | schema | rate |", "|---|---|---|"]
    for t in TOPICS:
        kind = "JSON " if t.encoding == "json" else ""
        rows.append(f"| `{t.name}` | {kind}`{t.schema}`: {t.doc} | {t.rate} |")
    return "\n".join(rows)
