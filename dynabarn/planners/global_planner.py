"""The global planner: Dijkstra on a grid of the known static map, as in the paper.

The paper's planners (and the learned ones' (g_x, g_y) input) take their local goal from
move_base's Dijkstra global planner on the static map. Here the static map is the world's
walls on a 0.1 m grid, inflated by the robot's circumscribed radius plus a margin.
Dijkstra runs once per (map, goal) from the goal over the 8-connected free cells and
yields a cost-to-go field with predecessors; any robot position then gets its path by
following predecessors, and a local goal by walking `lookahead` metres along that path.
The field is cached, so episodes in the same layout share it.

Replanning as needed: the static map does not know the obstacles the laser sees. When the
path's stretch inside the local costmap passes through an obstacle (closer than
`block_radius`), `plan_around` runs Dijkstra inside the costmap window from the robot,
with edge costs raised by the inflated costs (navfn-style) and blocked cells removed, and
joins it to the static field at the window cell with the least total cost to the goal.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from dynabarn.perception.map_distance import BOUNDS, grid_indices
from dynabarn.robot import JACKAL
from dynabarn.worlds.grid_graph import grid_dijkstra

RESOLUTION = 0.1
"""Grid cell size [m]."""
MARGIN = 0.05
"""[m] added to the robot's size when growing the known map."""
CIRCLE_INFLATION = JACKAL.width / 2 + MARGIN
"""Growth of static cylinders in the global map [m]: the Jackal's half width plus 5 cm."""


@dataclass(frozen=True)
class _Field:
    cost: np.ndarray  # (ny, nx) cost-to-go [m], inf where unreachable
    pred: list[int]  # flat predecessor towards the goal, -9999 at the goal / unreachable
    pred_array: np.ndarray  # the same as int32 (a batch of worlds walks them in numpy)
    nx: int
    ny: int


@functools.lru_cache(maxsize=64)
def _dijkstra_field(
    walls: tuple,
    goal: tuple[float, float],
    inflation: float,
    resolution: float,
    circles: tuple = (),
    circle_inflation: float = CIRCLE_INFLATION,
) -> _Field:
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
    # Around small static cylinders (BARN's grid) the robot can pass its narrow side first:
    # grow them by its half width (plus 5 cm), not by the circumscribed radius.
    for cx, cy, r in circles:
        occupied |= np.hypot(gx - cx, gy - cy) < r + circle_inflation
    goal_cell = _cell(goal[0], goal[1], nx, ny, resolution)
    cost, pred = grid_dijkstra(~occupied, goal_cell, resolution)
    return _Field(cost=cost, pred=pred.tolist(), pred_array=pred.astype(np.int32), nx=nx, ny=ny)


def _cell(x: float, y: float, nx: int, ny: int, resolution: float) -> int:
    i = min(max(int((y - BOUNDS[2]) / resolution), 0), ny - 1)
    j = min(max(int((x - BOUNDS[0]) / resolution), 0), nx - 1)
    return i * nx + j


CHAIN_SUFFIXES = 24
"""Further cells walked along the plan when a local goal's path is first asked for in a cell."""


class GlobalPlanner:
    """Dijkstra's global planner on the static map (walls).

    Args:
        walls: (n, 4) boxes (cx, cy, sx, sy) [m].
        goal: (2,) goal in the world [m].
        circles: (m, 3) static cylinders (x, y, radius) [m], part of the known map too.
        inflation: walls are grown by this much [m] (robot circumscribed radius + margin).
        resolution: grid cell [m].
        circle_inflation: static cylinders are grown by this much [m] (default: the
            Jackal's half width + 5 cm, so BARN's passages stay open).
    """

    def __init__(
        self,
        walls: np.ndarray,
        goal: np.ndarray,
        *,
        inflation: float = 0.4,
        resolution: float = RESOLUTION,
        circles: np.ndarray | None = None,
        circle_inflation: float = CIRCLE_INFLATION,
    ):
        self.goal = np.asarray(goal, dtype=np.float64)
        self.resolution = resolution
        key = tuple(tuple(round(float(v), 6) for v in w) for w in np.asarray(walls).reshape(-1, 4))
        circles = np.zeros((0, 3)) if circles is None else np.asarray(circles).reshape(-1, 3)
        ckey = tuple(tuple(round(float(v), 6) for v in c) for c in circles)
        self.field = _dijkstra_field(
            key, (float(goal[0]), float(goal[1])), float(inflation), float(resolution), ckey, float(circle_inflation)
        )
        x0, _, y0, _ = BOUNDS
        f = self.field
        self.cell_x = x0 + (np.arange(f.nx) + 0.5) * resolution
        self.cell_y = y0 + (np.arange(f.ny) + 0.5) * resolution
        self._replanner: LocalReplanner | None = None
        self._suffixes: dict[tuple[int, int], np.ndarray] = {}

    @classmethod
    def for_robot(
        cls, walls: np.ndarray, goal: np.ndarray, footprint: tuple[float, float], circles: np.ndarray | None = None
    ) -> GlobalPlanner:
        """The planners' global planner: walls grown by the footprint's circumscribed radius + 5 cm."""
        return cls(walls, goal, inflation=0.5 * math.hypot(*footprint) + MARGIN, circles=circles)

    def cost_to_go(self, x: float, y: float) -> float:
        f = self.field
        c = _cell(x, y, f.nx, f.ny, self.resolution)
        return float(f.cost.flat[c])

    def plan(self, x: float, y: float, max_cells: int | None = None) -> np.ndarray:
        """The path (n, 2) [m] from (x, y) to the goal: robot position, cell centres, goal.

        Falls back to the straight line when the robot's cell is unreachable (e.g. inside
        the inflated walls). With `max_cells`, only the path's first cells (without the goal
        unless it is reached within them): what a local goal needs, without walking on.
        """
        f = self.field
        c = _cell(x, y, f.nx, f.ny, self.resolution)
        if not math.isfinite(f.cost.flat[c]):
            return np.array([[x, y], self.goal])
        cells, cut = self._walk(c, f.nx * f.ny if max_cells is None else min(max_cells, f.nx * f.ny))
        out = self._points(cells, cut and max_cells is not None)
        out[0] = x, y  # the robot's position in place of its own cell's centre
        return out

    def _walk(self, c: int, limit: int) -> tuple[list[int], bool]:
        """The plan's cells from cell c (c first), at most `limit`; whether the walk was cut
        short before the goal."""
        cells, pred = [], self.field.pred
        while c >= 0 and len(cells) < limit:
            cells.append(c)
            c = pred[c]
        return cells, c >= 0

    def _points(self, cells: list[int], cut: bool) -> np.ndarray:
        """(len(cells) + 1 unless cut, 2): row 0 left for the caller, then the centres of the
        cells after the first, then the goal unless the walk was cut."""
        nx = self.field.nx
        idx = np.array(cells[1:], dtype=np.int64)
        out = np.empty((len(cells) + (0 if cut else 1), 2))
        out[1 : len(cells), 0] = self.cell_x[idx % nx]
        out[1 : len(cells), 1] = self.cell_y[idx // nx]
        if not cut:
            out[-1] = self.goal
        return out

    def plan_around(self, x: float, y: float, costmap, *, block_radius: float) -> np.ndarray:
        """The static plan, or, when it runs into an obstacle the costmap holds, a plan that
        goes around it inside the costmap window and follows the static field beyond."""
        path = self.plan(x, y)
        dist = costmap.lookup(path, costmap.distance, outside=np.inf)
        if dist[1:].min(initial=np.inf) >= block_radius:
            return path
        n = costmap.n
        if self._replanner is None or self._replanner.n != n:
            self._replanner = LocalReplanner(n, costmap.cfg.resolution)
        row, col = costmap.world_to_cell(np.array([x, y]))
        if not (0 <= row < n and 0 <= col < n):
            return path
        blocked = costmap.distance < block_radius
        blocked[row, col] = False  # never block the start
        local, pred = self._replanner.search(int(row * n + col), costmap.cost, blocked)
        res = costmap.cfg.resolution
        centres_x = (costmap.origin[0] + np.arange(n) + 0.5) * res
        centres_y = (costmap.origin[1] + np.arange(n) + 0.5) * res
        gx, gy = np.meshgrid(centres_x, centres_y)
        f = self.field
        cells_i, cells_j = grid_indices(gx, gy, self.resolution, f.nx, f.ny)
        total = local + f.cost[cells_i, cells_j].ravel()
        # Hand over to the static field only on the window's border (or at the goal):
        # inside, the static cost-to-go ignores the obstacles the detour goes around.
        handover = self._border_mask(n).copy()
        grow, gcol = costmap.world_to_cell(self.goal)
        if 0 <= grow < n and 0 <= gcol < n:
            handover[grow, gcol] = True
        total[~handover.ravel()] = np.inf
        best = int(np.argmin(total))
        if not math.isfinite(total[best]):
            return path
        chain = []
        c = best
        while c >= 0 and len(chain) < n * n:
            chain.append(c)
            c = pred[c]
        r, cc = np.divmod(np.array(chain[::-1]), n)
        detour = np.column_stack([centres_x[cc], centres_y[r]])
        onward = self.plan(float(detour[-1, 0]), float(detour[-1, 1]))
        return np.vstack([[x, y], detour[1:], onward[1:]])

    @staticmethod
    @functools.cache
    def _border_mask(n: int) -> np.ndarray:
        mask = np.zeros((n, n), dtype=bool)
        mask[0, :] = mask[-1, :] = mask[:, 0] = mask[:, -1] = True
        return mask

    def local_goal(
        self, x: float, y: float, lookahead: float, path: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(point `lookahead` metres along the path from (x, y), the path walked), world frame.

        Without `path`, only the plan's first floor(lookahead / resolution) + 3 cells are
        walked: consecutive cells are at least a resolution apart, so the point lies among
        them, and a cumulative sum's prefix is the prefix of the whole one (the same bits)."""
        if path is None:
            path = np.vstack([[x, y], self.plan_suffix(x, y, lookahead)])
        return points_along(path[None], lookahead)[0], path

    def plan_suffix(self, x: float, y: float, lookahead: float) -> np.ndarray:
        """`plan(x, y, max_cells)[1:]` for a local goal `lookahead` away: it depends on the
        robot's cell only, so it is kept per cell (a robot crosses a cell in several ticks)."""
        max_cells = math.floor(lookahead / self.resolution) + 3
        f = self.field
        cell = _cell(x, y, f.nx, f.ny, self.resolution)
        suffix = self._suffixes.get((cell, max_cells))
        if suffix is None:
            if not math.isfinite(f.cost.flat[cell]):
                suffix = self._suffixes[(cell, max_cells)] = self.plan(x, y, max_cells=max_cells)[1:]
            else:
                suffix = self._fill_suffixes(cell, max_cells)
        return suffix

    def _fill_suffixes(self, cell: int, max_cells: int) -> np.ndarray:
        """Walk the plan from `cell` CHAIN_SUFFIXES cells further than one suffix needs and
        keep the suffix of every cell on the way (slices of one array of cell centres): a
        robot that follows the plan meets them next. Each is `plan(...)[1:]` of its cell:
        the centres of its next max_cells - 1 cells, then the goal if it is among them."""
        cells, cut = self._walk(cell, max_cells + CHAIN_SUFFIXES)
        points = self._points(cells, cut)  # row j + 1: the centre of cells[j + 1] (or the goal)
        for j, cj in enumerate(cells):
            if j + max_cells < len(cells):  # cut short before the goal
                part = points[j + 1 : j + max_cells]
            elif not cut:
                part = points[j + 1 :]
            else:
                break  # its suffix would run past the walk
            self._suffixes.setdefault((cj, max_cells), part)
        return self._suffixes[(cell, max_cells)]

    def local_goal_in_robot(self, pose: np.ndarray, lookahead: float) -> np.ndarray:
        """The local goal `lookahead` metres along the plan from pose (x, y, yaw), in the robot frame."""
        return local_goals_in_robot([self], pose[None], lookahead)[0]


def local_goals_in_robot(planners: list[GlobalPlanner], poses: np.ndarray, lookahead: float) -> np.ndarray:
    """(W, 2) each pose (x, y, yaw) of (W, 3)'s local goal on its own planner, in its robot
    frame: `local_goal_in_robot` for many worlds in one pass (the same bits: every step is
    elementwise, each row's cumulative sum runs in order, paths padded by their last point)."""
    suffixes = [pl.plan_suffix(float(p[0]), float(p[1]), lookahead) for pl, p in zip(planners, poses, strict=True)]
    longest = max(len(s) for s in suffixes)
    paths = np.empty((len(planners), longest + 1, 2))
    paths[:, 0] = poses[:, :2]
    for row, suffix in zip(paths, suffixes, strict=True):
        row[1 : len(suffix) + 1] = suffix
        row[len(suffix) + 1 :] = suffix[-1]  # segments of length 0: the cumulative sum stays
    return goals_in_robot_frame(points_along(paths, lookahead), poses)


def goals_in_robot_frame(goals: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(W, 2) world points goals (W, 2) in the frames of poses (W, 3) (x, y, yaw)."""
    # As `to_robot_frame` turns one point: libm's cos and sin (numpy's may differ in the last bit).
    yaws = poses[:, 2].tolist()
    c = np.array([math.cos(a) for a in yaws])
    s = np.array([math.sin(a) for a in yaws])
    dx, dy = goals[:, 0] - poses[:, 0], goals[:, 1] - poses[:, 1]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy])


def points_along(paths: np.ndarray, lookahead: float) -> np.ndarray:
    """(W, 2) the point `lookahead` metres along each path of (W, P, 2) (its end if shorter)."""
    step = np.diff(paths, axis=1)
    seg = np.hypot(step[..., 0], step[..., 1])
    along = np.zeros((len(paths), paths.shape[1]))
    np.cumsum(seg, axis=1, out=along[:, 1:])
    out = paths[:, -1].copy()
    inside = np.flatnonzero(along[:, -1] > lookahead)
    if len(inside):
        k = (along[inside] < lookahead).sum(axis=1)  # searchsorted(along, lookahead) per row
        u = (lookahead - along[inside, k - 1]) / np.maximum(seg[inside, k - 1], 1e-12)
        a, b = paths[inside, k - 1], paths[inside, k]
        out[inside] = a + u[:, None] * (b - a)
    return out


class LocalReplanner:
    """Dijkstra inside a costmap window, joined to a static cost-to-go field."""

    def __init__(self, n: int, resolution: float, *, cost_factor: float = 3.0) -> None:
        from scipy.sparse import csr_matrix

        self.n = n
        self.resolution = resolution
        self.cost_factor = cost_factor
        idx = np.arange(n * n)
        i, j = np.divmod(idx, n)
        src, dst, length = [], [], []
        for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1), (0, -1), (-1, 0), (-1, -1), (-1, 1)):
            ii, jj = i + di, j + dj
            ok = (ii >= 0) & (ii < n) & (jj >= 0) & (jj < n)
            src.append(idx[ok])
            dst.append(ii[ok] * n + jj[ok])
            length.append(np.full(int(ok.sum()), resolution * math.hypot(di, dj)))
        self._src = np.concatenate(src)
        self._dst = np.concatenate(dst)
        self._len = np.concatenate(length)
        order = np.lexsort((self._dst, self._src))
        self._src, self._dst, self._len = self._src[order], self._dst[order], self._len[order]
        self._graph = csr_matrix((self._len.copy(), (self._src, self._dst)), shape=(n * n, n * n))
        self._graph.sort_indices()

    def search(self, start_cell: int, cost: np.ndarray, blocked: np.ndarray) -> tuple[np.ndarray, list[int]]:
        """Distances [m, weighted] from start_cell over the window and predecessors."""
        from scipy.sparse.csgraph import dijkstra

        c = cost.ravel() / 252.0
        w = self._len * (1.0 + self.cost_factor * 0.5 * (c[self._src] + c[self._dst]))
        b = blocked.ravel()
        w[b[self._src] | b[self._dst]] = 1e6  # effectively impassable, keeps the structure fixed
        self._graph.data[:] = w
        dist, pred = dijkstra(self._graph, directed=True, indices=start_cell, return_predecessors=True)
        dist[dist >= 1e6] = np.inf
        return dist, pred.tolist()
