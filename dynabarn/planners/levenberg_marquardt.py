"""Levenberg-Marquardt for small dense least-squares problems, the same bits on every machine.

TEB's band optimisation (`teb.py`) minimises 1/2 |r(x)|^2 over about 40 variables, a few
hundred times per episode, and every later tick starts from the band it returned: a
last-bit difference in one step becomes a different episode. So the solver may use only
arithmetic whose result is fixed by IEEE 754 and the order of operations:

- scipy's `least_squares(method="lm")` runs MINPACK, whose C translation in scipy 1.15-1.17
  reads one element past the Jacobian when `qrfac` recomputes a column norm (valgrind shows
  it), so a step could depend on whatever the heap holds there;
- `numpy.linalg` and `@` run on OpenBLAS (or another BLAS), whose kernels, chosen by CPU
  type and thread count, sum in different orders.

Here the normal equations are formed with elementwise products and numpy's pairwise sums
over each column's contiguous copy (a fixed tree of additions, whatever the Jacobian's
memory layout), and solved by a Cholesky factorisation written out column by column
(right-looking, so each column is a handful of vectorised operations). The algorithm is Marquardt's, as in
Madsen, Nielsen and Tingleff (2004), "Methods for non-linear least squares problems",
Algorithm 3.16: damping mu * diag(scale) with `scale` the largest diagonal of J^T J seen so
far (MINPACK's internal scaling), mu updated from the gain ratio (Nielsen's rule).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np


@dataclass(frozen=True)
class LMResult:
    """What `levenberg_marquardt` found."""

    x: np.ndarray
    """The best point evaluated."""
    cost: float
    """1/2 |r(x)|^2 there."""
    nfev: int
    """Residual evaluations (Jacobian evaluations not counted, as MINPACK's `lmder`)."""
    status: str
    """Why it stopped: `gtol` (gradient small), `xtol` (step small) or `max_nfev`."""


Pairs = tuple[np.ndarray, np.ndarray]
"""Entries (i, j), i <= j, of J^T J that can be nonzero: two index arrays."""


def gram(j: np.ndarray, pairs: Pairs | None = None) -> np.ndarray:
    """J^T J (n, n) for J (m, n) without BLAS: each entry the pairwise sum of its m products
    in row order. With `pairs`, only those entries are summed (the rest are zero: no row
    has both variables, so every product is zero)."""
    n = j.shape[1]
    upper, lower = pairs if pairs is not None else _triangle(n)
    columns = np.ascontiguousarray(j.T)
    values = (columns[upper] * columns[lower]).sum(axis=1)
    a = np.zeros((n, n))
    a[upper, lower] = values
    a[lower, upper] = values
    return a


def gradient(j: np.ndarray, r: np.ndarray) -> np.ndarray:
    """J^T r (n,), each entry the pairwise sum of its m products in row order."""
    return (np.ascontiguousarray(j.T) * r).sum(axis=1)


@lru_cache(maxsize=16)
def _triangle(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.triu_indices(n)


class CholeskySolver:
    """Solves a x = b for symmetric positive definite (n, n) a, again and again: the
    right-looking Cholesky factorisation a = L L^T with b carried along as an extra column
    (which is the forward substitution), then the back substitution. Each column is a
    division and one rank-one update, elementwise, so the same bits on every CPU; the views
    each column works on are made once, which halves the time of a 41-variable solve."""

    def __init__(self, n: int) -> None:
        self._work = work = np.empty((n, n + 1))
        # Column k's step: its pivot's place, its row right of the diagonal (divided in
        # place: by symmetry it is also L's column k, and its last entry is y_k), that row
        # without y_k as a column, and the trailing block the rank-one update goes to.
        self._steps = [(k, work[k, k + 1 :], work[k, k + 1 : n, None], work[k + 1 :, k + 1 :]) for k in range(n)]
        self._back = [(k, work[:k, k]) for k in range(n - 1, -1, -1)]

    def solve(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        n = len(b)
        work = self._work
        work[:, :n] = a
        work[:, n] = b
        pivots = []
        for k, row, column, trailing in self._steps:
            d = work.item(k, k)
            pivot = math.sqrt(d) if d > 0.0 else math.inf  # inf: the variable is frozen
            pivots.append(pivot)
            row /= pivot
            trailing -= column * row
        x = work[:, n].copy()
        for k, above in self._back:
            x[k] /= pivots[k]
            x[:k] -= above * x[k]
        return x


def cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with a x = b for a symmetric positive definite (n, n); a is not modified."""
    return CholeskySolver(len(b)).solve(a, b)


Evaluation = tuple[np.ndarray, Callable[[], np.ndarray]]
"""The residuals r(x) (m,) and what gives the Jacobian there (m, n) when it is needed."""


def levenberg_marquardt(
    fun: Callable[[np.ndarray], np.ndarray],
    jac: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    *,
    max_nfev: int,
    mu0: float = 1e-3,
    gtol: float = 1e-8,
    xtol: float = 1e-8,
) -> LMResult:
    """Minimise 1/2 |fun(x)|^2 from x0, with the Jacobian `jac(x)` (m, n): `minimise` with
    the two given apart."""
    return minimise(lambda x: (fun(x), lambda: jac(x)), x0, max_nfev=max_nfev, mu0=mu0, gtol=gtol, xtol=xtol)


def minimise(
    evaluate: Callable[[np.ndarray], Evaluation],
    x0: np.ndarray,
    *,
    max_nfev: int,
    pairs: Pairs | None = None,
    mu0: float = 1e-3,
    gtol: float = 1e-8,
    xtol: float = 1e-8,
) -> LMResult:
    """Minimise 1/2 |r(x)|^2 from x0, where `evaluate(x)` gives r(x) and the Jacobian's
    maker: a caller that gets both from one batched evaluation pays for one, and the
    Jacobian is made only at the points the search keeps. `pairs`: the entries of J^T J
    that can be nonzero, when the caller knows them (`gram`).

    Stops when the gradient's largest component is at most `gtol`, when a step is shorter
    than `xtol` (|x| + xtol), or after `max_nfev` residual evaluations."""
    x = np.array(x0, dtype=np.float64)
    r, jacobian = evaluate(x)
    nfev = 1
    cost = 0.5 * float(np.sum(r * r))
    j = jacobian()
    a = gram(j, pairs)
    g = gradient(j, r)
    solver = CholeskySolver(len(x))
    scale = np.maximum(np.diagonal(a).copy(), 0.0)
    mu, nu = mu0, 2.0
    status = "max_nfev"
    while nfev < max_nfev:
        if float(np.abs(g).max(initial=0.0)) <= gtol:
            status = "gtol"
            break
        floor = 1e-12 * float(scale.max(initial=0.0)) + 1e-300  # columns that never moved the residuals
        damping = mu * np.maximum(scale, floor)
        h = solver.solve(a + np.diag(damping), -g)
        if math.sqrt(float(np.sum(h * h))) <= xtol * (math.sqrt(float(np.sum(x * x))) + xtol):
            status = "xtol"
            break
        x_new = x + h
        r_new, jacobian = evaluate(x_new)
        nfev += 1
        cost_new = 0.5 * float(np.sum(r_new * r_new))
        predicted = 0.5 * float(np.sum(h * (damping * h - g)))
        gain = (cost - cost_new) / predicted if predicted > 0.0 and math.isfinite(cost_new) else -1.0
        if gain > 0.0:
            x, r, cost = x_new, r_new, cost_new
            j = jacobian()
            a = gram(j, pairs)
            g = gradient(j, r)
            np.maximum(scale, np.diagonal(a), out=scale)
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            nu = 2.0
        else:
            mu *= nu
            nu *= 2.0
    return LMResult(x=x, cost=cost, nfev=nfev, status=status)
