"""DynaBARN on MuJoCo: ground-robot navigation among moving obstacles.

The public surface, in the order data flows: profiles -> trajectories -> worlds -> MJCF
-> simulation -> recording. Names load on first use, so `import dynabarn` is cheap and
imports neither MuJoCo nor anything else until a name is needed (and changes no global
state: an application that renders offscreen chooses MuJoCo's OpenGL platform itself,
as the command-line tools do).

One exception, for reinforcement-learning users: when Gymnasium is already imported,
`import dynabarn` registers `dynabarn/DynaBARN-v0` (what `import dynabarn.learn` does), so
`import gymnasium as gym; import dynabarn; gym.make("dynabarn/DynaBARN-v0")` works.
"""

from __future__ import annotations

import importlib
import sys
from typing import TYPE_CHECKING

from dynabarn.exports import lazy_exports

_WHERE = {
    "DynabarnError": "dynabarn.errors",
    "EpisodeInfo": "dynabarn.interfaces",
    "EpisodeObserver": "dynabarn.interfaces",
    "EpisodeStart": "dynabarn.interfaces",
    "EpisodeResult": "dynabarn.metrics",
    "EpisodeRun": "dynabarn.runner",
    "EpisodeSpec": "dynabarn.runner",
    "EvalProtocol": "dynabarn.protocol",
    "Layout": "dynabarn.worlds.spec",
    "McapRecorder": "dynabarn.recording",
    "MotionProfile": "dynabarn.worlds.profiles",
    "ObstacleTracker": "dynabarn.perception",
    "Observation": "dynabarn.interfaces",
    "Obstacle": "dynabarn.worlds.spec",
    "ObstacleBehavior": "dynabarn.sim.behaviors",
    "ObstacleState": "dynabarn.interfaces",
    "Outcome": "dynabarn.metrics",
    "PAPER60": "dynabarn.worlds.generate",
    "PROFILE_SETS": "dynabarn.worlds.profiles",
    "PROTOCOLS": "dynabarn.protocol",
    "Planner": "dynabarn.interfaces",
    "ProfileError": "dynabarn.errors",
    "ProfileSet": "dynabarn.worlds.profiles",
    "Recording": "dynabarn.recording",
    "SHAPE_MIXES": "dynabarn.worlds.profiles",
    "STATIC_FIELDS": "dynabarn.worlds.profiles",
    "SchedulePlayer": "dynabarn.worlds.schedule",
    "ShapeMix": "dynabarn.worlds.profiles",
    "SimConfig": "dynabarn.sim",
    "Tick": "dynabarn.interfaces",
    "Topic": "dynabarn.recording.topics",
    "Simulation": "dynabarn.sim",
    "StaticField": "dynabarn.worlds.profiles",
    "TrackerConfig": "dynabarn.perception",
    "Tracks": "dynabarn.perception",
    "Trajectory": "dynabarn.worlds.trajectory",
    "WorldError": "dynabarn.errors",
    "WorldSpec": "dynabarn.worlds.spec",
    "CheckFailed": "dynabarn.checks",
    "CheckReport": "dynabarn.checks",
    "available_planners": "dynabarn.planners",
    "check_planner": "dynabarn.checks",
    "check_tracker": "dynabarn.checks",
    "generate_trajectory": "dynabarn.worlds.trajectory",
    "generate_world": "dynabarn.worlds.generate",
    "get_planner": "dynabarn.planners",
    "get_profile_set": "dynabarn.worlds.profiles",
    "get_protocol": "dynabarn.protocol",
    "load_model": "dynabarn.mjcf",
    "read_recording": "dynabarn.recording",
    "read_world": "dynabarn.mjcf",
    "register_planner": "dynabarn.planners",
    "register_protocol": "dynabarn.protocol",
    "resolve_world": "dynabarn.worldset",
    "run_spec": "dynabarn.runner",
    "write_world": "dynabarn.mjcf",
}

__all__ = [
    "PAPER60",
    "PROFILE_SETS",
    "PROTOCOLS",
    "SHAPE_MIXES",
    "STATIC_FIELDS",
    "CheckFailed",
    "CheckReport",
    "DynabarnError",
    "EpisodeInfo",
    "EpisodeObserver",
    "EpisodeResult",
    "EpisodeRun",
    "EpisodeSpec",
    "EpisodeStart",
    "EvalProtocol",
    "Layout",
    "McapRecorder",
    "MotionProfile",
    "Observation",
    "Obstacle",
    "ObstacleBehavior",
    "ObstacleState",
    "ObstacleTracker",
    "Outcome",
    "Planner",
    "ProfileError",
    "ProfileSet",
    "Recording",
    "SchedulePlayer",
    "ShapeMix",
    "SimConfig",
    "Simulation",
    "StaticField",
    "Tick",
    "Topic",
    "TrackerConfig",
    "Tracks",
    "Trajectory",
    "WorldError",
    "WorldSpec",
    "available_planners",
    "check_planner",
    "check_tracker",
    "generate_trajectory",
    "generate_world",
    "get_planner",
    "get_profile_set",
    "get_protocol",
    "load_model",
    "read_recording",
    "read_world",
    "register_planner",
    "register_protocol",
    "resolve_world",
    "run_spec",
    "write_world",
]


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)

if "gymnasium" in sys.modules:
    importlib.import_module("dynabarn.learn")  # registers the environment ids


if TYPE_CHECKING:  # for type checkers and editors: the same names, imported eagerly
    from dynabarn.checks import CheckFailed, CheckReport, check_planner, check_tracker
    from dynabarn.errors import DynabarnError, ProfileError, WorldError
    from dynabarn.interfaces import (
        EpisodeInfo,
        EpisodeObserver,
        EpisodeStart,
        Observation,
        ObstacleState,
        Planner,
        Tick,
    )
    from dynabarn.metrics import EpisodeResult, Outcome
    from dynabarn.mjcf import load_model, read_world, write_world
    from dynabarn.perception import ObstacleTracker, TrackerConfig, Tracks
    from dynabarn.planners import available_planners, get_planner, register_planner
    from dynabarn.protocol import PROTOCOLS, EvalProtocol, get_protocol, register_protocol
    from dynabarn.recording import McapRecorder, Recording, read_recording
    from dynabarn.recording.topics import Topic
    from dynabarn.runner import EpisodeRun, EpisodeSpec, run_spec
    from dynabarn.sim import SimConfig, Simulation
    from dynabarn.sim.behaviors import ObstacleBehavior
    from dynabarn.worlds.generate import PAPER60, generate_world
    from dynabarn.worlds.profiles import (
        PROFILE_SETS,
        SHAPE_MIXES,
        STATIC_FIELDS,
        MotionProfile,
        ProfileSet,
        ShapeMix,
        StaticField,
        get_profile_set,
    )
    from dynabarn.worlds.schedule import SchedulePlayer
    from dynabarn.worlds.spec import Layout, Obstacle, WorldSpec
    from dynabarn.worlds.trajectory import Trajectory, generate_trajectory
    from dynabarn.worldset import resolve_world
