"""Where the certificate's search (`certificate.certify`) may put the Jackal: occupancy
grids of one world, in the robot's configuration space.

- Walls and moving obstacles: each grown by the disc around the Jackal's footprint (safe at
  any heading), the obstacles stamped anew for every substep's time.
- The static field (a BARN grid of standing cylinders): the same disc, or, with
  `footprint`, the Jackal's own rectangle at its heading: one grid per heading bin, each
  cylinder grown by the rectangle turned to the bin's middle heading plus what a turn of
  half a bin sweeps. Passages the robot drives through lengthwise, but its disc does not
  fit, are then open to the search (the disc is 0.67 m across, the Jackal 0.43 m wide).

Every grid is also grown by the replay's tracking margin and a point's distance to its
cell's centre (the lookup's error), so a point found free is free within those margins.
"""

from __future__ import annotations

import math

import numpy as np

from dynabarn.determinism import snap_array
from dynabarn.protocol import EvalProtocol
from dynabarn.robot import JACKAL
from dynabarn.worlds.grid_graph import grid_dijkstra
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import WorldSpec

ROBOT_RADIUS = math.hypot(JACKAL.length / 2, JACKAL.width / 2)
"""[m] The disc around the Jackal's footprint: safe at any heading."""
HALF_FOOTPRINT = (JACKAL.length / 2, JACKAL.width / 2)
COST_RESOLUTION = 1e-3
"""[m] The grid the goal guidance's distances are snapped to (`Occupancy.cost_to_go`)."""
"""[m] The Jackal's rectangle: half its length (along its heading) and half its width."""


class Occupancy:
    """Occupancy grids of one world: the static part once, the obstacles per tick.

    Args:
        grid: cell side [m].
        tracking_margin: room for the replay's tracking error [m].
        substeps: collision checks per control tick (grids kept at once).
        footprint: the static field against the Jackal's rectangle per heading bin.
        headings: heading bins of those grids.
    """

    def __init__(
        self,
        world: WorldSpec,
        player: SchedulePlayer,
        protocol: EvalProtocol,
        *,
        grid: float,
        tracking_margin: float,
        substeps: int,
        footprint: bool = False,
        headings: int = 64,
    ) -> None:
        g = grid
        half = world.layout.arena_half_size
        sx = protocol.spawn[0]
        self.x0, self.y0 = min(-half, sx) - 1.0, -half - 1.0
        self.nx = math.ceil((max(half, sx) + 2.0 - self.x0) / g) + 1
        self.ny = math.ceil((half + 1.0 - self.y0) / g) + 1
        self.g, self.player = g, player
        self.margin = tracking_margin + g * math.sqrt(0.5)  # the lookup: a point's distance to its cell's centre
        self.base = ROBOT_RADIUS + self.margin
        cylinders = np.asarray(world.layout.cylinders, dtype=np.float64).reshape(-1, 3)
        self.static = self._walls(world)
        self.headings = headings if footprint else 0
        self.field: np.ndarray | None = None
        if footprint and len(cylinders):
            self.field = self._field_by_heading(cylinders)
        else:
            self.static |= self._field_as_discs(cylinders)
        obstacles = world.obstacles
        self.radii = np.array([o.radius + math.hypot(o.half_length, o.half_width) for o in obstacles])
        self.obstacle_speed = player.max_speed() if obstacles else 0.0
        self.now = np.empty((substeps, self.ny, self.nx), dtype=bool)

    @classmethod
    def of_search(cls, world: WorldSpec, player: SchedulePlayer, protocol: EvalProtocol, config) -> Occupancy:
        """The grids at a `certificate.CertificateConfig`'s resolution."""
        return cls(
            world,
            player,
            protocol,
            grid=config.grid,
            tracking_margin=config.tracking_margin,
            substeps=config.substeps,
            footprint=config.footprint,
            headings=config.footprint_headings,
        )

    def _centres(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x0 + self.g * np.arange(self.nx), self.y0 + self.g * np.arange(self.ny)

    def _walls(self, world: WorldSpec) -> np.ndarray:
        xs, ys = self._centres()
        X, Y = np.meshgrid(xs, ys)
        blocked = np.zeros(X.shape, dtype=bool)
        blocked[[0, -1], :] = blocked[:, [0, -1]] = True  # the edge: where points beyond it look
        for wall in world.layout.walls:  # boxes: the distance to a box, against the disc
            dx = np.maximum(np.abs(X - wall.centre[0]) - wall.size[0] / 2, 0.0)
            dy = np.maximum(np.abs(Y - wall.centre[1]) - wall.size[1] / 2, 0.0)
            blocked |= dx * dx + dy * dy < self.base**2
        return blocked

    def _field_as_discs(self, cylinders: np.ndarray) -> np.ndarray:
        xs, ys = self._centres()
        X, Y = np.meshgrid(xs, ys)
        blocked = np.zeros(X.shape, dtype=bool)
        for cx, cy, r in cylinders:
            blocked |= (X - cx) ** 2 + (Y - cy) ** 2 < (self.base + r) ** 2
        return blocked

    def _field_by_heading(self, cylinders: np.ndarray) -> np.ndarray:
        """(headings, ny, nx): where the robot's centre, at each bin's headings, brings its
        rectangle (grown by the margins and a half bin's sweep) within a cylinder."""
        g, bins = self.g, self.headings
        sweep = ROBOT_RADIUS * math.pi / bins  # a half bin's turn moves no point of it farther
        grow = self.margin + sweep
        reach = ROBOT_RADIUS + grow + float(cylinders[:, 2].max())
        w = math.ceil(reach / g)
        off = np.arange(-w, w + 1)
        cx = np.rint((cylinders[:, 0] - self.x0) / g).astype(np.int64)
        cy = np.rint((cylinders[:, 1] - self.y0) / g).astype(np.int64)
        ix = cx[:, None, None] + off[None, None, :]  # (n, 1, W)
        iy = cy[:, None, None] + off[None, :, None]  # (n, W, 1)
        # From each cell centre (a robot position) to the cylinder's centre, in the world.
        dx = cylinders[:, 0, None, None] - (self.x0 + g * ix)
        dy = cylinders[:, 1, None, None] - (self.y0 + g * iy)
        inside = (ix >= 0) & (ix < self.nx) & (iy >= 0) & (iy < self.ny)
        field = np.zeros((bins, self.ny, self.nx), dtype=bool)
        hl, hw = HALF_FOOTPRINT
        for b in range(bins):
            theta = (b + 0.5) * 2.0 * math.pi / bins
            c, s = math.cos(theta), math.sin(theta)
            along, across = dx * c + dy * s, dy * c - dx * s  # the cylinder in the robot's frame
            ex = np.maximum(np.abs(along) - hl, 0.0)
            ey = np.maximum(np.abs(across) - hw, 0.0)
            hit = (ex * ex + ey * ey < (cylinders[:, 2, None, None] + grow) ** 2) & inside
            n_, r_, c_ = np.nonzero(hit)
            field[b, iy[n_, r_, 0], ix[n_, 0, c_]] = True
        field |= self.static[None]  # the edges and walls, at every heading
        return field

    def stamp(self, times: np.ndarray, margins: np.ndarray) -> np.ndarray:
        """The grids (substeps, ny, nx) at `times` (substeps,): the static part and every
        obstacle grown by the robot's disc and `margins` (substeps,) [m]."""
        now = self.now
        now[:] = self.static
        if len(self.radii) == 0:
            return now
        xy, _ = self.player.positions_at(times)  # (S, n, 2)
        reach = self.base + self.radii[None, :] + margins[:, None]  # (S, n)
        w = math.ceil(float(reach.max()) / self.g)
        off = np.arange(-w, w + 1)
        cx = np.rint((xy[..., 0] - self.x0) / self.g).astype(np.int64)  # (S, n)
        cy = np.rint((xy[..., 1] - self.y0) / self.g).astype(np.int64)
        ix = cx[..., None, None] + off[None, None, None, :]  # (S, n, 1, W)
        iy = cy[..., None, None] + off[None, None, :, None]  # (S, n, W, 1)
        px = self.x0 + self.g * ix - xy[..., 0, None, None]
        py = self.y0 + self.g * iy - xy[..., 1, None, None]
        inside = (px * px + py * py < (reach**2)[..., None, None]) & (ix >= 0) & (ix < self.nx) & (iy >= 0)
        inside &= iy < self.ny
        s = np.broadcast_to(np.arange(len(times))[:, None, None, None], inside.shape)
        now[s[inside], np.broadcast_to(iy, inside.shape)[inside], np.broadcast_to(ix, inside.shape)[inside]] = True
        return now

    def cells(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The flat grid cells of points (x, y); beyond the grid, its edge."""
        ix = np.clip(np.rint((x - self.x0) / self.g), 0, self.nx - 1).astype(np.int64)
        iy = np.clip(np.rint((y - self.y0) / self.g), 0, self.ny - 1).astype(np.int64)
        return iy * self.nx + ix

    def lookup(self, grid: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The values of a (ny, nx) grid of this occupancy's cells at points (x, y)."""
        return grid.ravel()[self.cells(x, y)]

    def cost_to_go(self, goal: tuple[float, float]) -> np.ndarray:
        """(ny, nx) [m]: each cell's distance to the goal's through the cells where the robot
        can stand at some heading, the static part alone (walls and the field; inf where
        none leads): the certificate search's goal guidance (`CertificateConfig.beam`)."""
        free = ~self.static
        if self.field is not None:
            free &= ~self.field.all(axis=0)
        source = int(self.cells(np.array([goal[0]]), np.array([goal[1]]))[0])
        cost, _ = grid_dijkstra(free, source, self.g)
        # On a 1 mm grid: the order the search ranks states by is the same on every machine
        # (equal paths summed in another order differ in their last bits).
        return snap_array(cost, COST_RESOLUTION, out=cost)

    def free(self, sub: int, x: np.ndarray, y: np.ndarray, heading: np.ndarray) -> np.ndarray:
        """Whether the robot at poses (x, y, heading) is free at substep `sub`; beyond the
        grid is its edge, which is blocked (`_walls`)."""
        cell = self.cells(x, y)
        free = ~self.now[sub].ravel()[cell]
        if self.field is not None:
            bins = self.headings
            b = np.floor(np.mod(heading, 2.0 * math.pi) * (bins / (2.0 * math.pi))).astype(np.int64)
            free &= ~self.field.reshape(bins, -1)[np.minimum(b, bins - 1), cell]
        return free
