"""The simulator: a compiled world, its episodes and the loop that runs them.

config (SimConfig) -> laser -> simulation (a compiled world) -> behaviors (reactive
obstacles) -> episode (one episode, step by step) -> result (its metrics) -> loop
(`run_episode` with a planner and observers). What planners and observers receive lives
in `dynabarn.interfaces` (no MuJoCo); the names are handed on here too.
"""

from dynabarn.interfaces.events import EpisodeObserver, EpisodeStart, Tick
from dynabarn.interfaces.observation import EpisodeInfo, Observation, ObstacleState
from dynabarn.sim.config import SimConfig
from dynabarn.sim.episode import Episode
from dynabarn.sim.laser import Laser
from dynabarn.sim.loop import run_episode
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
