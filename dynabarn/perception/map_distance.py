"""Distance to the known map (walls and static cylinders) from a distance transform.

The map is what a robot may know before it drives: the arena's walls and, in static BARN
and mixed worlds, the static cylinders. Built once per episode over the planners' grid
extent (`BOUNDS`), then one lookup per point: the tracker drops laser returns that the map
explains, the oracle checks its rollouts against the static cylinders.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import distance_transform_edt

BOUNDS = (-11.0, 14.0, -11.0, 14.0)
"""Grid extent (x_min, x_max, y_min, y_max) [m] of every map grid (the global planner's, this
one): the arena plus both spawn points, and the static BARN worlds (x in [-4.5, 0], y in
[0, 13])."""


def grid_indices(x: np.ndarray, y: np.ndarray, resolution: float, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """Row (y) and column (x) indices of points in a grid of `resolution` over BOUNDS,
    clipped to the grid (points outside read its edge)."""
    i = np.clip(((y - BOUNDS[2]) / resolution).astype(np.int64), 0, ny - 1)
    j = np.clip(((x - BOUNDS[0]) / resolution).astype(np.int64), 0, nx - 1)
    return i, j


class MapDistance:
    """Distance [m] to the nearest surface of the known map, from a distance transform at
    `resolution` (a lookup per point). Outside the map's shapes it is within one
    `resolution` of the exact distance, erring towards the map by at most half a cell.

    Args:
        circles: (n, 3) static cylinders (x, y, radius) [m].
        walls: (m, 4) boxes (cx, cy, sx, sy) [m]; none by default.
        resolution: cell side [m].
    """

    def __init__(self, circles: np.ndarray, walls: np.ndarray | None = None, *, resolution: float = 0.025) -> None:
        self.resolution = res = resolution
        x0, x1, y0, y1 = BOUNDS
        self.nx, self.ny = round((x1 - x0) / res), round((y1 - y0) / res)
        cx = x0 + (np.arange(self.nx) + 0.5) * res
        cy = y0 + (np.arange(self.ny) + 0.5) * res
        free = np.ones((self.ny, self.nx), dtype=bool)
        for x, y, r in np.asarray(circles, dtype=np.float64).reshape(-1, 3):  # a few cells each
            i0, i1 = np.searchsorted(cy, [y - r - res, y + r + res])
            j0, j1 = np.searchsorted(cx, [x - r - res, x + r + res])
            gx, gy = np.meshgrid(cx[j0:j1], cy[i0:i1])
            free[i0:i1, j0:j1] &= np.hypot(gx - x, gy - y) > r
        for bx, by, sx, sy in np.zeros((0, 4)) if walls is None else np.asarray(walls, dtype=np.float64).reshape(-1, 4):
            i0, i1 = np.searchsorted(cy, [by - sy / 2, by + sy / 2])
            j0, j1 = np.searchsorted(cx, [bx - sx / 2, bx + sx / 2])
            free[i0:i1, j0:j1] = False
        # Distance from each cell centre to the nearest occupied cell's centre, less half a
        # cell: errs towards the map by at most half a cell.
        self.distance = distance_transform_edt(free) * res - 0.5 * res

    def lookup(self, xy: np.ndarray) -> np.ndarray:
        """Distances (...) for points (..., 2)."""
        return self.at(xy[..., 0], xy[..., 1])

    def at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distances for points given as x and y arrays of one shape."""
        return self.distance[grid_indices(x, y, self.resolution, self.nx, self.ny)]
