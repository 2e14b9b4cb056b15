"""Perception: what the robot makes of its own laser and odometry, below the planners
that use it and above the simulator (it sees only `Observation` and `EpisodeInfo`).

- `map_distance`: distance to the known map (walls, static cylinders);
- `map_scan`: the ranges the laser would read of the known map alone;
- `detect`: obstacle detections in one scan (segments, split arcs, known-radius circles);
- `tracks`: the `Tracks` a tracker reports, and their constant-velocity future;
- `tracker`: association (Hungarian), a constant-velocity Kalman filter per track, births,
  coasting through occlusion and expiry.
"""

from dynabarn.perception.detect import Detections, DetectorConfig, ObstacleDetector
from dynabarn.perception.map_distance import MapDistance
from dynabarn.perception.map_scan import MapScan
from dynabarn.perception.tracker import ObstacleTracker, TrackerConfig
from dynabarn.perception.tracks import Tracks

__all__ = [
    "Detections",
    "DetectorConfig",
    "MapDistance",
    "MapScan",
    "ObstacleDetector",
    "ObstacleTracker",
    "TrackerConfig",
    "Tracks",
]
