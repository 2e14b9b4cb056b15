"""The one table of recording topics: name, schema, rate, what it holds, how it is made.

Everything else follows this table: the recorder opens a channel per topic and writes the
per-tick JSON topics from it, `dynabarn-replay` plots the fields a topic names in `plots`,
and the README's topic table is `markdown_table()` (a test compares them).

A new JSON topic computed from each control tick is one `Topic` here with a `per_tick`
function (return None to skip a tick); the README's "Extending" walks through one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dynabarn.determinism import snap_array
from dynabarn.sim.events import Tick

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
    """

    name: str
    schema: str
    rate: str
    doc: str
    json_schema: dict | None = None
    per_tick: Callable[[Tick], dict | None] | None = None
    plots: tuple[str, ...] = ()

    @property
    def encoding(self) -> str:
        return "protobuf" if self.json_schema is None else "json"


def _number(doc: str) -> dict:
    return {"type": "number", "description": doc}


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


def _planner_debug(tick: Tick) -> dict | None:
    return {k: _on_grid(v) for k, v in tick.debug.items()} if tick.debug else None


METADATA = Topic(
    "/world/metadata",
    "dynabarn.EpisodeStart",
    "once",
    "world, keyframes, protocol, planner and config, seed, clock offset, versions (dynabarn, mujoco, "
    "numpy, scipy; torch for bc/td3)",
    json_schema={"type": "object"},
)
STATIC = Topic(
    "/world/static",
    "foxglove.SceneUpdate",
    "once",
    "walls (cubes), goal region (cylinder), static cylinders (entity `static_obstacles`, when the world has any)",
)
GOAL = Topic("/goal", "foxglove.PoseInFrame", "once", "the goal, frame `world`")
OBSTACLES = Topic(
    "/world/obstacles",
    "foxglove.SceneUpdate",
    "10 Hz",
    "cylinders for the cylinder and capsule obstacles (a capsule as a horizontal cylinder along its axis), "
    "cubes for the boxes, each list in world order; `dynabarn.recording.obstacle_track` undoes it",
)
SCAN = Topic("/scan", "foxglove.LaserScan", "10 Hz", "frame `world`, pose = the laser's pose")
POSE = Topic("/robot/pose", "foxglove.PoseInFrame", "50 Hz", "frame `world`")
CMD = Topic(
    "/cmd_vel",
    "dynabarn.Command",
    "10 Hz",
    "v, w sent; raw_v, raw_w from the planner (on the 1 um/s command grid)",
    json_schema={
        "type": "object",
        "properties": {
            "v": _number("forward speed sent [m/s]"),
            "w": _number("yaw rate sent [rad/s]"),
            "raw_v": _number("planner output before limits [m/s]"),
            "raw_w": _number("planner output before limits [rad/s]"),
        },
    },
    per_tick=_command,
    plots=("v", "w"),
)
METRICS = Topic(
    "/metrics",
    "dynabarn.StepMetrics",
    "10 Hz",
    "measured v, w, clearance, distance to goal",
    json_schema={
        "type": "object",
        "properties": {
            "v": {"type": "number"},
            "w": {"type": "number"},
            "clearance": {"type": "number"},
            "distance_to_goal": {"type": "number"},
        },
    },
    per_tick=_step_metrics,
    plots=("clearance", "distance_to_goal"),
)
DEBUG = Topic(
    "/planner/debug",
    "dynabarn.PlannerDebug",
    "10 Hz",
    "e.g. a local plan, on a 0.1 mm grid, when the planner has any",
    json_schema={"type": "object"},
    per_tick=_planner_debug,
)
RESULT = Topic(
    "/episode/result",
    "dynabarn.EpisodeResult",
    "once, at the end",
    "the metrics, without wall-clock fields",
    json_schema={"type": "object"},
)

TOPICS: tuple[Topic, ...] = (METADATA, STATIC, GOAL, OBSTACLES, SCAN, POSE, CMD, METRICS, DEBUG, RESULT)
"""Every topic, in the README's order; per-tick JSON topics are written in this order."""

# The names under which the rest of the package knows them.
TOPIC_METADATA, TOPIC_STATIC, TOPIC_GOAL = METADATA.name, STATIC.name, GOAL.name
TOPIC_OBSTACLES, TOPIC_SCAN, TOPIC_POSE = OBSTACLES.name, SCAN.name, POSE.name
TOPIC_CMD, TOPIC_METRICS, TOPIC_DEBUG, TOPIC_RESULT = CMD.name, METRICS.name, DEBUG.name, RESULT.name


def markdown_table() -> str:
    """The README's topic table."""
    rows = ["| topic | schema | rate |", "|---|---|---|"]
    for t in TOPICS:
        kind = "JSON " if t.encoding == "json" else ""
        rows.append(f"| `{t.name}` | {kind}`{t.schema}`: {t.doc} | {t.rate} |")
    return "\n".join(rows)


def plotted() -> list[tuple[Topic, str]]:
    """(topic, field) of every time series the replay draws, in table order."""
    return [(t, f) for t in TOPICS for f in t.plots]
