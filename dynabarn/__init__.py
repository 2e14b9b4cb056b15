"""DynaBARN on MuJoCo: ground-robot navigation among moving obstacles.

The public surface, in the order data flows: profiles -> trajectories -> worlds -> MJCF
-> simulation -> recording.
"""

import os as _os

# Offscreen rendering needs an OpenGL platform before mujoco is imported: without a display,
# use EGL (Mesa, no GPU needed); with one (or Xvfb), MuJoCo's default GLFW.
if "MUJOCO_GL" not in _os.environ and not _os.environ.get("DISPLAY"):
    _os.environ["MUJOCO_GL"] = "egl"

from dynabarn.errors import DynabarnError, ProfileError, WorldError
from dynabarn.metrics import EpisodeResult, Outcome
from dynabarn.mjcf import load_model, read_world, write_world
from dynabarn.planners import (
    EpisodeInfo,
    Observation,
    ObstacleState,
    Planner,
    available_planners,
    get_planner,
    register_planner,
)
from dynabarn.protocol import PROTOCOLS, EvalProtocol, get_protocol, register_protocol
from dynabarn.recording import McapRecorder, Recording, read_recording
from dynabarn.sim import SimConfig, Simulation, run_episode
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

__all__ = [
    "PAPER60",
    "PROFILE_SETS",
    "PROTOCOLS",
    "SHAPE_MIXES",
    "STATIC_FIELDS",
    "DynabarnError",
    "EpisodeInfo",
    "EpisodeResult",
    "EvalProtocol",
    "Layout",
    "McapRecorder",
    "MotionProfile",
    "Observation",
    "Obstacle",
    "ObstacleState",
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
    "Trajectory",
    "WorldError",
    "WorldSpec",
    "available_planners",
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
    "run_episode",
    "write_world",
]
