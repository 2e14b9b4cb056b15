"""Local planners: the interface (base), the registry (built-ins, run-time registrations
and the entry-point group `dynabarn.planners`), the classical baselines (dwa, teb with
costmap and global_planner), the privileged oracle, the simple floors and the learned
baselines (learned/). A new planner: a `Planner` subclass plus one registry line or entry
point (docs/tutorials/planner.md)."""

from dynabarn.errors import EndEpisode
from dynabarn.interfaces import EpisodeInfo, Observation, ObstacleState, Planner
from dynabarn.planners.from_code import planner_spec
from dynabarn.planners.presets import planner_presets, read_planner_config
from dynabarn.planners.registry import available_planners, get_planner, register_planner

__all__ = [
    "EndEpisode",
    "EpisodeInfo",
    "Observation",
    "ObstacleState",
    "Planner",
    "available_planners",
    "get_planner",
    "planner_presets",
    "planner_spec",
    "read_planner_config",
    "register_planner",
]
