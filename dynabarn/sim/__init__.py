"""The simulator: a compiled world, its episodes and the loop that runs them.

config (SimConfig) -> laser -> simulation (a compiled world) -> behaviors (reactive
obstacles) -> episode (one episode, step by step) -> result (its metrics) -> loop
(`run_episode` with a planner and observers). `observation` and `events` are what
planners and observers receive.
"""

from dynabarn.sim.config import SimConfig
from dynabarn.sim.episode import Episode
from dynabarn.sim.events import EpisodeObserver, EpisodeStart, Tick
from dynabarn.sim.laser import Laser
from dynabarn.sim.loop import run_episode
from dynabarn.sim.observation import EpisodeInfo, Observation, ObstacleState
from dynabarn.sim.simulation import Simulation

__all__ = [
    "Episode",
    "EpisodeInfo",
    "EpisodeObserver",
    "EpisodeStart",
    "Laser",
    "Observation",
    "ObstacleState",
    "SimConfig",
    "Simulation",
    "Tick",
    "run_episode",
]
