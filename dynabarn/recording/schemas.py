"""JSON Schemas (draft 2020-12) of the recording's JSON topics.

Foxglove shows a JSON topic's fields from its schema (message path completion, plots), and
any JSON tool can validate a message against it; a test validates every message of real
recordings. The result's schema is read off `EpisodeResult`'s fields, so it follows them.
"""

from __future__ import annotations

import dataclasses

from dynabarn.metrics import OPTIONAL_FIELDS, EpisodeResult, Outcome

DIALECT = "https://json-schema.org/draft/2020-12/schema"

WALL_CLOCK_FIELDS = ("rtf", "wall_time", "planner_ms_mean", "planner_ms_p95")
"""Result fields that depend on the machine's speed, kept out of recordings."""
MACHINE_FIELDS = (*WALL_CLOCK_FIELDS, "machine")
"""Result fields kept out of the recording's messages (the machine block goes into the
MCAP metadata record `dynabarn.machine`), so the messages are byte-identical across machines."""


def number(doc: str) -> dict:
    return {"type": "number", "description": doc}


def nullable_number(doc: str) -> dict:
    """A number that is null when it has no finite value (strict JSON has no NaN)."""
    return {"type": ["number", "null"], "description": doc}


def obj(doc: str, properties: dict, required: tuple[str, ...] = (), *, closed: bool = False) -> dict:
    schema = {"type": "object", "description": doc, "properties": properties}
    if required:
        schema["required"] = list(required)
    if closed:
        schema["additionalProperties"] = False
    return schema


def points_xy(doc: str) -> dict:
    """A polyline: a list of [x, y] points [m] in the world frame."""
    return {
        "type": "array",
        "description": doc,
        "items": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 3},
    }


def document(title: str, schema: dict) -> dict:
    """A topic's schema as written: the dialect and its schema name as the title (Foxglove
    shows the title)."""
    return {"$schema": DIALECT, "title": title, **schema}


_JSON_TYPES = {
    "float": ["number", "null"],
    "int": "integer",
    "str": "string",
    "dict": "object",
    "bool": "boolean",
    "dict | None": "object",
}


def result_schema() -> dict:
    """`/episode/result`: every field of `EpisodeResult` but the machine-dependent ones."""
    properties = {}
    for f in dataclasses.fields(EpisodeResult):
        if f.name in MACHINE_FIELDS:
            continue
        kind = str(f.type)
        if kind == "Outcome":
            properties[f.name] = {"enum": [o.value for o in Outcome]}
        else:
            properties[f.name] = {"type": _JSON_TYPES[kind]}
    required = [f.name for f in dataclasses.fields(EpisodeResult) if f.name in properties]
    required = [name for name in required if name not in OPTIONAL_FIELDS]
    return obj("the episode's outcome and metrics (dynabarn.metrics.EpisodeResult)", properties, tuple(required))


_OBSTACLE = obj(
    "one moving obstacle",
    {
        "name": {"type": "string"},
        "shape": {"enum": ["cylinder", "box", "capsule"]},
        "radius": number("[m]"),
        "behavior": {"type": "string"},
    },
    ("name",),
)

METADATA_SCHEMA = obj(
    "everything needed to rebuild and judge the episode",
    {
        "world": obj(
            "the world's description (dynabarn.worlds.WorldSpec.metadata())",
            {
                "name": {"type": "string"},
                "layout": obj(
                    "walls, goal, static cylinders",
                    {"goal": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}},
                ),
                "obstacles": {"type": "array", "items": _OBSTACLE},
            },
            ("name", "layout", "obstacles"),
        ),
        "world_file": {"type": "string", "description": "the world file, relative to the project when inside it"},
        "world_sha256": {"type": "string", "pattern": "^[0-9a-f]{64}$"},
        "protocol": obj("the evaluation protocol (dynabarn.protocol)", {"name": {"type": "string"}}, ("name",)),
        "planner": {"type": "string", "description": "planner name, NAME@PRESET for a shipped preset"},
        "planner_config": {"type": "object"},
        "seed": {"type": "integer"},
        "clock_offset": number("the obstacles' clock offset drawn from the seed [s]"),
        "sim_config": obj("physics step and control rate", {"dt": number("[s]")}),
        "versions": {"type": "object", "additionalProperties": {"type": "string"}},
        "robot": obj(
            "the Jackal as the planner sees it",
            {
                "footprint": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2},
                "laser_angles": {"type": "array", "description": "[first, last, count]"},
                "laser_range": {"type": "array", "items": {"type": "number"}},
                "laser_offset": {"type": "array", "items": {"type": "number"}},
                "laser_z": number("[m]"),
            },
        ),
        "keyframes": {
            "type": "object",
            "description": "obstacle name -> [[t, x, y], ...]",
            "additionalProperties": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
        },
        "source": {"enum": ["human", "oracle", "planner"]},
        "synthetic": {"type": "boolean"},
    },
    ("world", "world_sha256", "protocol", "planner", "seed", "clock_offset", "versions", "robot", "keyframes"),
)


def numbers(doc: str) -> dict:
    return {"type": "array", "description": doc, "items": {"type": "number"}}


TRACKS_SCHEMA = obj(
    "the planner's tracked obstacles at one control tick (dynabarn.perception.Tracks), on the 0.1 mm grid",
    {
        "ids": {"type": "array", "description": "track identities", "items": {"type": "integer"}},
        "positions": points_xy("centres [m], world frame"),
        "velocities": points_xy("velocities [m/s], world frame"),
        "sizes": numbers("radius of a circle around each obstacle [m]"),
        "position_std": numbers("standard deviation of each centre (the larger axis) [m]"),
        "age": numbers("seconds since each track was born"),
        "last_seen": numbers("time of each track's last detection [s]"),
    },
    ("ids", "positions", "velocities", "sizes", "position_std", "age", "last_seen"),
    closed=True,
)

DEBUG_SCHEMA = obj(
    "planner internals, on the 0.1 mm debug grid; planners may add fields of their own",
    {
        "local_plan": points_xy("the local plan (DWA's best rollout, TEB's band, the oracle's)"),
        "global_plan": points_xy("the global plan the local planner follows, from the robot onward"),
    },
)
