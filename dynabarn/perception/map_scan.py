"""What the laser would see of the known map alone (`MapScan`): the walls and the standing
cylinders every planner is given (`EpisodeInfo.walls`, `.static_obstacles`), cast in
closed form from the laser's pose along every beam, without noise.

Beside the real scan it says which returns are the map's and which are something else:
where the scan is shorter than the map's range, an obstacle the map does not hold is in
the way; where the map's range is shorter than the scan could see, the map knows of a
cylinder behind one. It is how a learned student sees the map its teacher plans on
(`FeatureConfig.static_map`).
"""

from __future__ import annotations

import numpy as np

from dynabarn.determinism import sincos
from dynabarn.interfaces import EpisodeInfo
from dynabarn.robot import mounted_pose
from dynabarn.worlds.ray_cast import box_ranges, circle_ranges


class MapScan:
    """Noise-free ranges (n_beams,) [m] to the known map from a robot pose; range_max where
    the beam meets none of it."""

    def __init__(self, info: EpisodeInfo) -> None:
        self.angles = np.asarray(info.laser_angles, dtype=np.float64)
        self.offset = np.asarray(info.laser_offset, dtype=np.float64)
        self.range_max = float(info.laser_range[1])
        self.walls = np.asarray(info.walls, dtype=np.float64).reshape(-1, 4)
        self.cylinders = np.asarray(info.static_obstacles, dtype=np.float64).reshape(-1, 3)

    def __call__(self, pose: np.ndarray) -> np.ndarray:
        # The laser sits at its offset in the robot frame, as the simulator mounts it.
        ox, oy, yaw = (float(v) for v in mounted_pose(pose, self.offset))
        s, c = sincos(self.angles + yaw)  # the same bits on every CPU (numpy's cos and sin are not)
        out = box_ranges(ox, oy, yaw, self.angles, self.walls, self.range_max, (c, s))
        if len(self.cylinders):
            cylinders = circle_ranges(ox, oy, yaw, self.angles, self.cylinders, self.range_max, (c, s))
            np.minimum(out, cylinders, out=out)
        return out
