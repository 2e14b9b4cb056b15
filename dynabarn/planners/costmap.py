"""A rolling-window local costmap from the laser, as ROS's costmap_2d does it (vectorised).

The window (default 8 m x 8 m at 10 cm) stays centred on the robot: when the robot moves
by whole cells the grid shifts and newly exposed cells start unknown (free). Every scan
first clears the cells each beam passes through (ray tracing up to its return or the
raytrace range), then marks the cells where beams returned within the obstacle range.
Inflation turns the obstacle cells into costs with a Euclidean distance transform:
lethal (254) within `inscribed_radius`, then `252 * exp(-cost_scaling * (d - inscribed))`
out to `inflation_radius`, 0 beyond (costmap_2d's inflation layer).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.ndimage import distance_transform_edt

from dynabarn.determinism import exp, hypot
from dynabarn.interfaces.planner import CheckedConfig

LETHAL = 254
INSCRIBED = 253


@dataclass
class CostmapConfig(CheckedConfig):
    size: float = 8.0
    """Window side [m]."""
    resolution: float = 0.1
    """Cell side [m]."""
    obstacle_range: float = 4.0
    """Beams returning closer than this mark obstacles [m]."""
    raytrace_range: float = 4.5
    """Beams clear free space up to this far [m]."""
    inscribed_radius: float = 0.27
    """Distance below which the robot certainly collides [m] (half width plus margin)."""
    inflation_radius: float = 0.9
    """Costs fall to 0 beyond this distance from an obstacle [m]."""
    cost_scaling: float = 6.0
    """Exponential decay rate of inflated costs [1/m]."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "size": (1.0, 40.0),
        "resolution": (0.02, 1.0),
        "obstacle_range": (0.0, 30.0),
        "raytrace_range": (0.0, 30.0),
        "inscribed_radius": (0.0, 2.0),
        "inflation_radius": (0.0, 5.0),
        "cost_scaling": (0.0, 100.0),
    }
    ORDERED: ClassVar[tuple[tuple[str, str], ...]] = (("inscribed_radius", "inflation_radius"),)
    """Lethal inside the inscribed radius, inflated out to the inflation radius: not crossed."""


def with_costmap(kwargs: dict, what: str) -> dict:
    """A planner's keyword configuration with its `costmap.KEY` entries (or a `costmap`
    dict) gathered into one checked `CostmapConfig` under "costmap"."""
    from dynabarn.interfaces import config_from_kwargs, nested_config

    return nested_config(kwargs, "costmap", lambda sub: config_from_kwargs(CostmapConfig, sub, f"{what} costmap"), what)


class LocalCostmap:
    """Rolling-window occupancy and cost grid around the robot."""

    def __init__(self, config: CostmapConfig | None = None) -> None:
        self.cfg = config or CostmapConfig()
        c = self.cfg
        self.n = round(c.size / c.resolution)
        self.occupied = np.zeros((self.n, self.n), dtype=bool)
        self.cost = np.zeros((self.n, self.n), dtype=np.float64)
        self.distance = np.full((self.n, self.n), np.inf)  # to the nearest obstacle cell [m]
        self.origin = np.zeros(2, dtype=np.int64)  # world cell index of grid cell (0, 0)
        self._index = np.arange(self.n)
        self._initialised = False

    # -- geometry ---------------------------------------------------------------------
    def world_to_cell(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Grid (row, col) of world points (..., 2); may fall outside the grid."""
        r = self.cfg.resolution
        col = np.floor(xy[..., 0] / r).astype(np.int64) - self.origin[0]
        row = np.floor(xy[..., 1] / r).astype(np.int64) - self.origin[1]
        return row, col

    def lookup(self, xy: np.ndarray, grid: np.ndarray | None = None, outside: float = 0.0) -> np.ndarray:
        """Values of `grid` (default: costs) at world points (..., 2); `outside` beyond the window."""
        grid = self.cost if grid is None else grid
        row, col = self.world_to_cell(xy)
        inside = (row >= 0) & (row < self.n) & (col >= 0) & (col < self.n)
        out = np.full(row.shape, outside, dtype=np.float64)
        out[inside] = grid[row[inside], col[inside]]
        return out

    def _recentre(self, x: float, y: float) -> None:
        r = self.cfg.resolution
        new = np.array([math.floor(x / r) - self.n // 2, math.floor(y / r) - self.n // 2], dtype=np.int64)
        if not self._initialised:
            self.origin = new
            self._initialised = True
            return
        shift = new - self.origin
        if not shift.any():
            return
        dx, dy = int(shift[0]), int(shift[1])
        moved = np.zeros_like(self.occupied)
        if abs(dx) < self.n and abs(dy) < self.n:
            src = self.occupied[max(dy, 0) : self.n + min(dy, 0), max(dx, 0) : self.n + min(dx, 0)]
            moved[max(-dy, 0) : self.n + min(-dy, 0), max(-dx, 0) : self.n + min(-dx, 0)] = src
        self.occupied = moved
        self.origin = new

    # -- update -------------------------------------------------------------------------
    def update(
        self, pose: np.ndarray, scan: np.ndarray, angles: np.ndarray, laser_offset: np.ndarray, range_max: float
    ) -> None:
        """Clear and mark from one scan taken at robot pose (x, y, yaw), then inflate.

        Clearing is ray tracing done the other way round, for speed: every cell within
        the raytrace range and the field of view is looked up in polar coordinates
        (its beam and its range), and cleared when it lies before that beam's return.
        """
        x, y, yaw = float(pose[0]), float(pose[1]), float(pose[2])
        self._recentre(x, y)
        c, s = math.cos(yaw), math.sin(yaw)
        lx = x + c * laser_offset[0] - s * laser_offset[1]
        ly = y + s * laser_offset[0] + c * laser_offset[1]
        cfg = self.cfg
        res = cfg.resolution
        # Cell centres relative to the laser, in the laser's frame.
        cx = (self.origin[0] + self._index + 0.5) * res - lx  # (n,) along columns
        cy = (self.origin[1] + self._index + 0.5) * res - ly  # (n,) along rows
        fx = c * cx[None, :] + s * cy[:, None]
        fy = -s * cx[None, :] + c * cy[:, None]
        rng = hypot(fx, fy)
        bearing = np.arctan2(fy, fx)
        a0 = angles[0]
        da = (angles[-1] - angles[0]) / (len(angles) - 1)
        beam = np.rint((bearing - a0) / da).astype(np.int64)
        in_fov = (beam >= 0) & (beam < len(angles))
        np.clip(beam, 0, len(angles) - 1, out=beam)
        reach = np.minimum(scan[beam] - res, cfg.raytrace_range)
        self.occupied[in_fov & (rng < reach)] = False
        # Marking: returns within the obstacle range (not max-range "no return").
        hit = (scan < cfg.obstacle_range) & (scan < range_max - 1e-6)
        a = angles[hit] + yaw
        ends = np.column_stack([lx + scan[hit] * np.cos(a), ly + scan[hit] * np.sin(a)])
        row, col = self.world_to_cell(ends)
        inside = (row >= 0) & (row < self.n) & (col >= 0) & (col < self.n)
        self.occupied[row[inside], col[inside]] = True
        self._inflate()

    def _inflate(self) -> None:
        cfg = self.cfg
        if not self.occupied.any():
            self.cost.fill(0.0)
            self.distance.fill(np.inf)
            return
        d = distance_transform_edt(~self.occupied) * cfg.resolution
        self.distance = d
        # Whole numbers, as costmap_2d's unsigned char costs: the same on every CPU, so
        # equal costs tie exactly in the planners' comparisons and Dijkstra.
        # The decay only where it is kept (within the inflation radius): elementwise, so the
        # same bits there as over the whole grid.
        inflated = d <= cfg.inflation_radius
        cost = np.zeros_like(d)
        cost[inflated] = np.rint(252.0 * exp(-cfg.cost_scaling * (d[inflated] - cfg.inscribed_radius)))
        cost[d <= cfg.inscribed_radius] = INSCRIBED
        cost[self.occupied] = LETHAL
        self.cost = cost
