"""The simulator: a compiled world, its episodes and the loop that runs them.

config (SimConfig) -> laser -> simulation (a compiled world) -> behaviors (reactive
obstacles) -> episode (one episode, step by step) -> result (its metrics) -> loop
(`run_episode` with a planner and observers). What planners and observers receive lives
in `dynabarn.interfaces` (no MuJoCo); the names are handed on here too.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dynabarn.exports import lazy_exports

if TYPE_CHECKING:
    from dynabarn.interfaces.events import EpisodeObserver, EpisodeStart, Tick
    from dynabarn.interfaces.observation import EpisodeInfo, Observation, ObstacleState
    from dynabarn.sim.episode import Episode
    from dynabarn.sim.laser import Laser
    from dynabarn.sim.loop import EpisodeLoop, run_episode
    from dynabarn.sim.simulation import Simulation
    from dynabarn.sim_config import SimConfig

_HOMES = {
    "EpisodeObserver": "dynabarn.interfaces.events",
    "EpisodeStart": "dynabarn.interfaces.events",
    "Tick": "dynabarn.interfaces.events",
    "EpisodeInfo": "dynabarn.interfaces.observation",
    "Observation": "dynabarn.interfaces.observation",
    "ObstacleState": "dynabarn.interfaces.observation",
    "SimConfig": "dynabarn.sim_config",
    "Episode": "dynabarn.sim.episode",
    "Laser": "dynabarn.sim.laser",
    "EpisodeLoop": "dynabarn.sim.loop",
    "run_episode": "dynabarn.sim.loop",
    "Simulation": "dynabarn.sim.simulation",
}
"""Where each name of the package lives: imported when first asked for (PEP 562), so that
`dynabarn.sim.behaviors` or `dynabarn.sim_config` can be imported without MuJoCo."""


__getattr__, __dir__ = lazy_exports(__name__, _HOMES)

__all__ = [
    "Episode",
    "EpisodeInfo",
    "EpisodeLoop",
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
