"""The 720-beam scans of many worlds at once, in closed form (the vector environment's laser).

`mj_multiRay` casts one world's rays from one point; a batch of worlds would need a
Python call per world, and its cost grows with every geom (about 7 us per obstacle per
scan). The worlds of the paper's kind hold only axis-aligned wall boxes and standing
cylinders, whose intersections with a horizontal ray have closed forms; here they are
computed for every world in one vectorised pass:

- cylinders: each is tested only against the beams inside its angular extent from its
  world's laser (np.repeat over the extents: the work is the number of beams that can hit,
  not beams x obstacles); t = b - sqrt(b^2 - (|c - o|^2 - r^2)), b = u . (c - o);
- walls: the slab method against each box's x and y faces, every beam of every world,
  one box at a time (the temporaries of all boxes at once outgrow the cache: 1.7x slower).

The directions are those `Laser.cast` uses (cos and sin of the same angles), so the
ranges agree with `mj_multiRay`'s to rounding (1e-12 m), far below the 1 mm grid the
scan is snapped to; a test compares the two over many worlds and poses. `supports(sim)`
says whether a world is of this kind (no boxes or capsules among its obstacles, no static
field); the others keep `mj_multiRay`.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import mujoco
import numpy as np

from dynabarn.robot import JACKAL
from dynabarn.sim.simulation import Simulation


@dataclass(frozen=True)
class _WorldRays:
    """What the closed form needs of one compiled world, read once."""

    supported: bool
    walls: np.ndarray  # (k, 6) cx, cy, half x, half y, centre z, bounding radius
    obstacles: np.ndarray  # (n, 2) every obstacle geom's centre height and bounding radius


_facts: weakref.WeakKeyDictionary[Simulation, _WorldRays] = weakref.WeakKeyDictionary()


def _world_rays(sim: Simulation) -> _WorldRays:
    facts = _facts.get(sim)
    if facts is None:
        mujoco.mj_kinematics(sim.model, sim.data)  # geom positions (derived only: the episode's state is untouched)
        facts = _facts[sim] = _WorldRays(
            supported=all(o.shape == "cylinder" and o.top > JACKAL.laser_z for o in sim.world.obstacles)
            and len(sim.static_cylinders) == 0,
            walls=_wall_geoms(sim),
            obstacles=_obstacle_z_rbound(sim),
        )
    return facts


def supports(sim: Simulation) -> bool:
    """True when the world's laser sees only walls and standing cylinders taller than the laser."""
    return _world_rays(sim).supported


class BatchCaster:
    """Noise-free ranges (W, n_beams) for W worlds of `supports`' kind."""

    def __init__(self, sims: list[Simulation]) -> None:
        self.angles = sims[0].laser.angles
        self.n = len(self.angles)
        self.range_max = sims[0].laser.params.laser_range_max
        self._step = (self.angles[-1] - self.angles[0]) / (self.n - 1)
        self._cos, self._sin = np.cos(self.angles), np.sin(self.angles)
        walls = [_world_rays(s).walls for s in sims]
        k = max(len(w) for w in walls)
        # Worlds with fewer walls get boxes far outside every range.
        box = np.tile(np.array([1e6, 1e6, 1.0, 1.0, 0.0, 1.0]), (len(sims), k, 1))
        for i, w in enumerate(walls):
            box[i, : len(w)] = w
        self.wall_lo = box[..., :2] - box[..., 2:4]  # (W, k, 2)
        self.wall_hi = box[..., :2] + box[..., 2:4]
        self.wall_centre = np.concatenate([box[..., :2], box[..., 4:5]], axis=-1)  # (W, k, 3)
        self.wall_rbound = box[..., 5]
        shape = (len(sims), self.n)
        self._wall_buffers = [np.empty(shape) for _ in range(5)] + [np.empty(shape, bool) for _ in range(2)]
        self.radii = np.concatenate([s.radii for s in sims])
        self.world_of = np.repeat(np.arange(len(sims)), [len(s.radii) for s in sims])
        z_rb = np.concatenate([_world_rays(s).obstacles for s in sims]).reshape(-1, 2)
        self.obstacle_z, self.obstacle_rbound = z_rb[:, 0], z_rb[:, 1]

    def cast(self, origins: np.ndarray, yaws: np.ndarray, centres: np.ndarray) -> np.ndarray:
        """origins (W, 3) of the lasers, yaws (W,), every world's obstacle centres concatenated (N, 2)."""
        # cos(angle + yaw) by the angle sum: no transcendental per beam (the directions
        # differ from Laser.cast's in the last bit, the ranges by 1e-15 m).
        cy, sy = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
        ux = self._cos[None, :] * cy - self._sin[None, :] * sy
        uy = self._sin[None, :] * cy + self._cos[None, :] * sy
        out = self._walls(origins, ux, uy)
        self._cylinders(out, origins, yaws, centres, ux, uy)
        # Like mj_multiRay, a hit beyond the range is reported as it is (the scan clips it
        # after the noise); only a beam that hits nothing reads range_max.
        out[np.isinf(out)] = self.range_max
        return out

    def _walls(self, origins: np.ndarray, ux: np.ndarray, uy: np.ndarray) -> np.ndarray:
        """(W, n) the nearest wall along every beam (inf: none), by the slab method one box
        at a time over every world's beams (arrays that stay in cache; buffers reused)."""
        out = np.full(ux.shape, np.inf)
        t1, t2, near, far, other, hit, ahead = self._wall_buffers
        # mj_multiRay leaves out a geom whose bounding sphere lies beyond the range.
        culled = np.linalg.norm(self.wall_centre - origins[:, None, :], axis=-1) - self.wall_rbound > self.range_max
        lo = self.wall_lo - origins[:, None, :2]  # (W, k, 2): the boxes' corners from each laser
        hi = self.wall_hi - origins[:, None, :2]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_x, inv_y = 1.0 / ux, 1.0 / uy
            for j in range(lo.shape[1]):
                np.multiply(lo[:, j, 0, None], inv_x, out=t1)
                np.multiply(hi[:, j, 0, None], inv_x, out=t2)
                np.fmin(t1, t2, out=near)
                np.fmax(t1, t2, out=far)
                np.multiply(lo[:, j, 1, None], inv_y, out=t1)
                np.multiply(hi[:, j, 1, None], inv_y, out=t2)
                np.maximum(near, np.fmin(t1, t2, out=other), out=near)
                np.minimum(far, np.fmax(t1, t2, out=other), out=far)
                np.less_equal(near, far, out=hit)
                hit &= np.greater(near, 0.0, out=ahead)
                hit &= ~culled[:, j, None]
                np.minimum(out, near, out=out, where=hit)
        return out

    def _cylinders(self, out, origins, yaws, centres, ux, uy) -> None:
        if len(centres) == 0:
            return
        w = self.world_of
        d = centres - origins[w, :2]
        r = self.radii
        dist = np.hypot(d[:, 0], d[:, 1])
        dz = self.obstacle_z - origins[w, 2]
        # mj_multiRay's culling: the bounding sphere beyond the range.
        near = (np.sqrt(dist * dist + dz * dz) - self.obstacle_rbound <= self.range_max) & (dist > r)
        d, r, dist, w = d[near], r[near], dist[near], w[near]
        theta = np.arctan2(d[:, 1], d[:, 0]) - yaws[w]
        theta = (theta + np.pi) % (2 * np.pi) - np.pi
        alpha = np.arcsin(r / dist)
        # One beam of margin each side: the extent's edges are the grazing rays.
        lo = np.maximum(np.ceil((theta - alpha - self.angles[0]) / self._step) - 1, 0).astype(np.int64)
        hi = np.minimum(np.floor((theta + alpha - self.angles[0]) / self._step) + 1, self.n - 1).astype(np.int64)
        counts = np.maximum(hi - lo + 1, 0)
        total = int(counts.sum())
        if total == 0:
            return
        which = np.repeat(np.arange(len(counts)), counts)
        beam = lo[which] + np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        ww = w[which]
        dc = np.take(d, which, axis=0)  # np.take: fancy indexing of rows is far slower
        b = ux[ww, beam] * dc[:, 0] + uy[ww, beam] * dc[:, 1]
        disc = b * b - (dist[which] ** 2 - r[which] ** 2)
        hit = (disc >= 0) & (b > 0)
        t = b[hit] - np.sqrt(disc[hit])
        np.minimum.at(out, (ww[hit], beam[hit]), t)


def _wall_geoms(sim: Simulation) -> np.ndarray:
    """(k, 6) the walls' boxes as the model has them: cx, cy, half x, half y, centre z, bounding radius."""
    m = sim.model
    rows = []
    for g in range(m.ngeom):
        if m.geom(g).name.startswith("wall") and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            x, y, z = sim.data.geom_xpos[g]
            rows.append([x, y, m.geom_size[g][0], m.geom_size[g][1], z, m.geom_rbound[g]])
    return np.array(rows).reshape(-1, 6)


def _obstacle_z_rbound(sim: Simulation) -> np.ndarray:
    """(n, 2) every obstacle geom's centre height and bounding radius."""
    m = sim.model
    out = np.zeros((len(sim.radii), 2))
    for g in np.flatnonzero(sim.obstacle_of_geom >= 0):
        out[sim.obstacle_of_geom[g]] = (sim.data.geom_xpos[g][2], m.geom_rbound[g])
    return out
