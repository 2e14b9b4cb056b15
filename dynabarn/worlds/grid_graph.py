"""Shortest paths over a world's free cells: one grid Dijkstra for every user of the map.

The global planner's cost-to-go (`planners.global_planner`) and the certificate search's
goal guidance (`sim.certificate`) both ask the same question of a boolean grid of free
cells: how far is every cell from one cell, moving between 8-neighbours that are both free
(steps of one cell side, diagonals of sqrt(2) of it). `scipy.sparse.csgraph.dijkstra`
answers it on the grid's graph; the graph is built here once, in one order, so every
caller gets the same bits.
"""

from __future__ import annotations

import math

import numpy as np


def grid_dijkstra(free: np.ndarray, source: int, resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """Distances (ny, nx) [m] from the flat cell `source` through the free cells of `free`
    (ny, nx) (inf where none leads), and each cell's flat predecessor on its way to the
    source (-9999 at the source and where none leads)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    ny, nx = free.shape
    flat = free.ravel()
    ia, ja = np.divmod(np.arange(nx * ny), nx)
    rows, cols, weights = [], [], []
    # Half of the 8 neighbourhoods; the graph is undirected.
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        ib, jb = ia + di, ja + dj
        ok = (ib < ny) & (jb >= 0) & (jb < nx)
        na, nb = ia[ok] * nx + ja[ok], ib[ok] * nx + jb[ok]
        keep = flat[na] & flat[nb]
        rows.append(na[keep])
        cols.append(nb[keep])
        weights.append(np.full(int(keep.sum()), resolution * math.hypot(di, dj)))
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    w = np.concatenate(weights)
    graph = coo_matrix((w, (r, c)), shape=(nx * ny, nx * ny)).tocsr()
    cost, pred = dijkstra(graph, directed=False, indices=source, return_predecessors=True)
    return cost.reshape(ny, nx), pred
