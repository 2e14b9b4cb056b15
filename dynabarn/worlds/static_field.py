"""BARN-style fields of static cylinders for mixed worlds (beyond the paper).

BARN (Perille et al. 2020) builds a world from a grid: cells are filled at random, a
cellular automaton smooths them into clumps and passages, and a world is kept only if a
path through it exists. `generate_static_field` does the same for a `StaticField`
profile and returns the cylinders (x, y, r) for a world's `Layout`. It only draws from
the generator it is given, so a world's field is fixed by its seed.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from dynabarn.errors import WorldError
from dynabarn.worlds.profiles import StaticField

ROBOT_RADIUS = 0.333
"""[m] the Jackal's circumscribed radius: a field must let it through, room to turn included."""
CROSSING_MARGIN = 0.03
"""[m] kept between the robot's disc and a cylinder in the crossing check."""
MAX_ATTEMPTS = 200


def _smooth(filled: np.ndarray, iterations: int) -> np.ndarray:
    """BARN's cellular automaton: >= 5 filled of 8 neighbours fills a cell, <= 3 empties it."""
    for _ in range(iterations):
        p = np.pad(filled, 1).astype(np.int8)
        n = sum(
            p[1 + di : p.shape[0] - 1 + di, 1 + dj : p.shape[1] - 1 + dj]
            for di in (-1, 0, 1)
            for dj in (-1, 0, 1)
            if di or dj
        )
        filled = np.where(n >= 5, True, np.where(n <= 3, False, filled))
    return filled


def _enclosed(filled: np.ndarray) -> np.ndarray:
    """Filled cells whose 8 neighbours are all filled (outside the grid counts as free)."""
    p = np.pad(filled, 1)
    out = filled.copy()
    h, w = filled.shape
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            out &= p[1 + di : 1 + di + h, 1 + dj : 1 + dj + w]
    return out


def blocked_for_robot(filled: np.ndarray, cell: float, radius: float) -> np.ndarray:
    """Cells where the robot's centre would come within CROSSING_MARGIN of a cylinder."""
    reach = (radius + ROBOT_RADIUS + CROSSING_MARGIN) / cell
    k = int(np.ceil(reach))
    blocked = np.zeros_like(filled)
    padded = np.pad(filled, k)
    h, w = filled.shape
    for di in range(-k, k + 1):
        for dj in range(-k, k + 1):
            if di * di + dj * dj < reach * reach:
                blocked |= padded[k + di : k + di + h, k + dj : k + dj + w]
    return blocked


def crosses(blocked: np.ndarray) -> bool:
    """Whether free cells connect the field's last row (spawn side, high x) to its first
    (goal side, low x), moving between 4-neighbours. Rows are x, columns are y."""
    free = ~blocked
    h = free.shape[0]
    seen = np.zeros_like(free)
    queue = deque((h - 1, j) for j in np.flatnonzero(free[h - 1]))
    for i, j in queue:
        seen[i, j] = True
    while queue:
        i, j = queue.popleft()
        if i == 0:
            return True
        for a, b in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)):
            if 0 <= a < h and 0 <= b < free.shape[1] and free[a, b] and not seen[a, b]:
                seen[a, b] = True
                queue.append((a, b))
    return False


def generate_static_field(rng: np.random.Generator, field: StaticField) -> tuple[tuple[float, float, float], ...]:
    """Draw a crossable field; its cylinders (x, y, radius) sorted by x then y."""
    nx = round((field.x_range[1] - field.x_range[0]) / field.cell)
    ny = round((field.y_range[1] - field.y_range[0]) / field.cell)
    xs = field.x_range[0] + (np.arange(nx) + 0.5) * field.cell
    ys = field.y_range[0] + (np.arange(ny) + 0.5) * field.cell
    fill = float(rng.uniform(*field.fill))
    for _ in range(MAX_ATTEMPTS):
        filled = _smooth(rng.random((nx, ny)) < fill, field.smooth_iterations)
        if crosses(blocked_for_robot(filled, field.cell, field.radius)):
            i, j = np.nonzero(filled & ~_enclosed(filled))
            cx, cy = np.round(xs[i], 6).tolist(), np.round(ys[j], 6).tolist()
            return tuple((x, y, field.radius) for x, y in zip(cx, cy, strict=True))
    raise WorldError(
        f"static field {field.name!r}: no crossable field in {MAX_ATTEMPTS} draws at fill {fill:.2f}; lower the fill"
    )
