"""The global planner: Dijkstra on a grid of the known static map, as in the paper.

The paper's planners (and the learned ones' (g_x, g_y) input) take their local goal from
move_base's Dijkstra global planner on the static map. Here the static map is the world's
walls on a 0.1 m grid, inflated by the robot's circumscribed radius plus a margin.
Dijkstra runs once per (map, goal) from the goal over the 8-connected free cells and
yields a cost-to-go field with predecessors; any robot position then gets its path by
following predecessors, and a local goal by walking `lookahead` metres along that path.
The field is cached, so episodes in the same layout share it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

RESOLUTION = 0.1
"""Grid cell size [m]."""
BOUNDS = (-11.0, 14.0, -11.0, 11.0)
"""Grid extent (x_min, x_max, y_min, y_max) [m]: the arena plus both spawn points."""


@dataclass(frozen=True)
class _Field:
    cost: np.ndarray  # (ny, nx) cost-to-go [m], inf where unreachable
    pred: list[int]  # flat predecessor towards the goal, -9999 at the goal / unreachable
    nx: int
    ny: int


@functools.lru_cache(maxsize=64)
def _dijkstra_field(walls: tuple, goal: tuple[float, float], inflation: float, resolution: float) -> _Field:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    x0, x1, y0, y1 = BOUNDS
    nx = round((x1 - x0) / resolution)
    ny = round((y1 - y0) / resolution)
    xs = x0 + (np.arange(nx) + 0.5) * resolution
    ys = y0 + (np.arange(ny) + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)
    occupied = np.zeros((ny, nx), dtype=bool)
    for cx, cy, sx, sy in walls:
        dx = np.maximum(np.abs(gx - cx) - sx / 2, 0.0)
        dy = np.maximum(np.abs(gy - cy) - sy / 2, 0.0)
        occupied |= np.hypot(dx, dy) < inflation
    free = ~occupied.ravel()
    idx = np.arange(nx * ny).reshape(ny, nx)
    rows, cols, weights = [], [], []
    ia, ja = np.divmod(idx.ravel(), nx)
    # Half of the 8 neighbourhoods; the graph is undirected.
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        ib, jb = ia + di, ja + dj
        ok = (ib < ny) & (jb >= 0) & (jb < nx)
        na, nb = ia[ok] * nx + ja[ok], ib[ok] * nx + jb[ok]
        keep = free[na] & free[nb]
        rows.append(na[keep])
        cols.append(nb[keep])
        weights.append(np.full(int(keep.sum()), resolution * math.hypot(di, dj)))
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    w = np.concatenate(weights)
    graph = coo_matrix((w, (r, c)), shape=(nx * ny, nx * ny)).tocsr()
    goal_cell = _cell(goal[0], goal[1], nx, ny, resolution)
    cost, pred = dijkstra(graph, directed=False, indices=goal_cell, return_predecessors=True)
    return _Field(cost=cost.reshape(ny, nx), pred=pred.tolist(), nx=nx, ny=ny)


def _cell(x: float, y: float, nx: int, ny: int, resolution: float) -> int:
    i = min(max(int((y - BOUNDS[2]) / resolution), 0), ny - 1)
    j = min(max(int((x - BOUNDS[0]) / resolution), 0), nx - 1)
    return i * nx + j


class GlobalPlanner:
    """Dijkstra's global planner on the static map (walls).

    Args:
        walls: (n, 4) boxes (cx, cy, sx, sy) [m].
        goal: (2,) goal in the world [m].
        inflation: walls are grown by this much [m] (robot circumscribed radius + margin).
        resolution: grid cell [m].
    """

    def __init__(self, walls: np.ndarray, goal: np.ndarray, *, inflation: float = 0.4, resolution: float = RESOLUTION):
        self.goal = np.asarray(goal, dtype=np.float64)
        self.resolution = resolution
        key = tuple(tuple(round(float(v), 6) for v in w) for w in np.asarray(walls).reshape(-1, 4))
        self.field = _dijkstra_field(key, (float(goal[0]), float(goal[1])), float(inflation), float(resolution))
        x0, _, y0, _ = BOUNDS
        f = self.field
        self._cx = x0 + (np.arange(f.nx) + 0.5) * resolution
        self._cy = y0 + (np.arange(f.ny) + 0.5) * resolution

    def cost_to_go(self, x: float, y: float) -> float:
        f = self.field
        c = _cell(x, y, f.nx, f.ny, self.resolution)
        return float(f.cost.flat[c])

    def plan(self, x: float, y: float) -> np.ndarray:
        """The path (n, 2) [m] from (x, y) to the goal: robot position, cell centres, goal.

        Falls back to the straight line when the robot's cell is unreachable (e.g. inside
        the inflated walls).
        """
        f = self.field
        c = _cell(x, y, f.nx, f.ny, self.resolution)
        if not math.isfinite(f.cost.flat[c]):
            return np.array([[x, y], self.goal])
        cells = []
        pred = f.pred
        while c >= 0 and len(cells) < f.nx * f.ny:
            cells.append(c)
            c = pred[c]
        ij = np.divmod(np.array(cells), f.nx)
        pts = np.column_stack([self._cx[ij[1]], self._cy[ij[0]]])
        return np.vstack([[x, y], pts[1:], self.goal])

    def local_goal(self, x: float, y: float, lookahead: float) -> tuple[np.ndarray, np.ndarray]:
        """(point `lookahead` metres along the path from (x, y), the path itself), world frame."""
        path = self.plan(x, y)
        seg = np.hypot(*np.diff(path, axis=0).T)
        along = np.concatenate([[0.0], np.cumsum(seg)])
        if along[-1] <= lookahead:
            return path[-1].copy(), path
        k = int(np.searchsorted(along, lookahead))
        u = (lookahead - along[k - 1]) / max(seg[k - 1], 1e-12)
        return path[k - 1] + u * (path[k] - path[k - 1]), path


def to_robot_frame(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """World points (n, 2) into the robot frame of pose (x, y, yaw)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = np.asarray(points) - pose[:2]
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
