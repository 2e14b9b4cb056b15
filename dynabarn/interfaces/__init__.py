"""What planners and observers are written against, without MuJoCo or the simulator.

`Observation` (what a planner sees each control tick), `ObstacleState` (the true obstacles,
for privileged planners), `EpisodeInfo` (the static facts at reset), `Planner` (the base
class: `reset(info)`, `act(obs) -> (v, w)`), `EpisodeObserver` (the base with no-op hooks:
`on_start`, `on_tick`, `on_poses`, `on_end`) and the events it receives (`EpisodeStart`,
`Tick`). This layer imports numpy and `dynabarn.errors` only, so an out-of-tree planner,
the ROS bridge's stack side or an analysis script pays for neither MuJoCo nor the
simulator (a test imports it in a fresh interpreter).
"""

from dynabarn.errors import EndEpisode
from dynabarn.interfaces.events import EpisodeObserver, EpisodeStart, Period, Tick
from dynabarn.interfaces.observation import EpisodeInfo, Observation, ObstacleState
from dynabarn.interfaces.planner import CheckedConfig, Planner, config_from_kwargs, nested_config, recorded_config
from dynabarn.interfaces.tracker import BaseTrackerConfig, Tracker

__all__ = [
    "BaseTrackerConfig",
    "CheckedConfig",
    "EndEpisode",
    "EpisodeInfo",
    "EpisodeObserver",
    "EpisodeStart",
    "Observation",
    "ObstacleState",
    "Period",
    "Planner",
    "Tick",
    "Tracker",
    "config_from_kwargs",
    "nested_config",
    "recorded_config",
]
