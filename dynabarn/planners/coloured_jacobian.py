"""Forward-difference Jacobians of batched residuals, by column colouring (Curtis, Powell
and Reid 1974), with the bits of one batch row per variable.

A residual function that evaluates a batch of points in one call (rows of z) gives the
forward-difference Jacobian from 1 + n rows: z, then z with each variable stepped alone.
Variables that move no residual in common can be stepped in the same row: each residual
still sees only its own variable's step, the same value as alone, so every entry of the
Jacobian has the same bits, from about a dozen rows for TEB's 41 variables instead of 42.
Which residuals each variable moves is found by setting it to NaN, which flows through
every arithmetic operation (a function that compares or clips it away must not use this).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

Residuals = Callable[[np.ndarray], np.ndarray]
"""(B, n_var) points -> (B, n_res) residuals, elementwise the same whatever B."""


@dataclass(frozen=True)
class Colouring:
    """Which residuals each variable moves, and the batch row each variable is stepped in."""

    colours: np.ndarray
    """(n_var,) the batch row of each variable: no two variables of a colour move the same
    residual (greedy colouring in variable order)."""
    n_colours: int
    rows: np.ndarray
    """Residual of each entry of the Jacobian that can be nonzero."""
    cols: np.ndarray
    """Variable of each such entry."""

    @classmethod
    def of(cls, moves: np.ndarray) -> Colouring:
        """From `moves` (n_var, n_res): whether variable i moves residual k."""
        colours = np.empty(len(moves), dtype=np.int64)
        taken: list[np.ndarray] = []  # per colour: the residuals its variables move
        for i, residuals in enumerate(moves):
            free = [c for c, t in enumerate(taken) if not (t & residuals).any()]
            if free:
                colours[i] = free[0]
                taken[free[0]] |= residuals
            else:
                colours[i] = len(taken)
                taken.append(residuals.copy())
        cols, rows = np.nonzero(moves)
        return cls(colours, len(taken), rows, cols)

    @classmethod
    def probe(cls, residuals: Residuals, z: np.ndarray) -> Colouring:
        """Set each variable of z to NaN in turn: the residuals it reaches are the ones it moves."""
        with np.errstate(invalid="ignore"):
            moves = np.isnan(residuals(z[None, :] + np.diag(np.full(len(z), np.nan))))
        return cls.of(moves)


def residuals_and_jacobian(
    residuals: Residuals, z: np.ndarray, colouring: Colouring
) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
    """The residuals at z and what gives the forward-difference Jacobian (n_res, n_var)
    there (steps of 1e-6 relative, at least 1e-6), from one batched evaluation."""
    h = 1e-6 * np.maximum(1.0, np.abs(z))
    steps = np.zeros((colouring.n_colours, len(z)))
    steps[colouring.colours, np.arange(len(z))] = h
    r = residuals(np.vstack([z[None], z[None, :] + steps]))

    def jacobian() -> np.ndarray:
        rows, cols = colouring.rows, colouring.cols
        j = np.zeros((r.shape[1], len(z)))
        j[rows, cols] = (r[1 + colouring.colours[cols], rows] - r[0, rows]) / h[cols]
        return j

    return r[0], jacobian
