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

Here the normal equations are formed with elementwise products and sums along fixed axes,
and solved by a Cholesky factorisation written out column by column (right-looking, so
each column is a handful of vectorised operations). The algorithm is Marquardt's, as in
Madsen, Nielsen and Tingleff (2004), "Methods for non-linear least squares problems",
Algorithm 3.16: damping mu * diag(scale) with `scale` the largest diagonal of J^T J seen so
far (MINPACK's internal scaling), mu updated from the gain ratio (Nielsen's rule).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

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


def gram(j: np.ndarray) -> np.ndarray:
    """J^T J (n, n) for J (m, n), summed over the m rows in order: no BLAS."""
    return (j[:, :, None] * j[:, None, :]).sum(axis=0)


def cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with a x = b for a symmetric positive definite (n, n); a is not modified.

    Right-looking Cholesky a = L L^T, then forward and back substitution, each column one
    or two vectorised updates (elementwise, so the same bits on every CPU)."""
    n = len(b)
    s = a.copy()
    low = np.zeros_like(a)
    for k in range(n):
        pivot = math.sqrt(s[k, k]) if s[k, k] > 0.0 else math.inf  # inf: the variable is frozen
        col = s[k:, k] / pivot
        low[k:, k] = col
        low[k, k] = pivot
        tail = col[1:]
        s[k + 1 :, k + 1 :] -= tail[:, None] * tail[None, :]
    y = b.astype(np.float64, copy=True)
    for k in range(n):
        y[k] /= low[k, k]
        y[k + 1 :] -= low[k + 1 :, k] * y[k]
    for k in range(n - 1, -1, -1):
        y[k] /= low[k, k]
        y[:k] -= low[k, :k] * y[k]
    return y


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
    """Minimise 1/2 |fun(x)|^2 from x0, with the Jacobian `jac(x)` (m, n).

    Stops when the gradient's largest component is at most `gtol`, when a step is shorter
    than `xtol` (|x| + xtol), or after `max_nfev` residual evaluations."""
    x = np.array(x0, dtype=np.float64)
    r = fun(x)
    nfev = 1
    cost = 0.5 * float(np.sum(r * r))
    j = jac(x)
    a = gram(j)
    g = (j * r[:, None]).sum(axis=0)
    scale = np.maximum(np.diagonal(a).copy(), 0.0)
    mu, nu = mu0, 2.0
    status = "max_nfev"
    while nfev < max_nfev:
        if float(np.abs(g).max(initial=0.0)) <= gtol:
            status = "gtol"
            break
        floor = 1e-12 * float(scale.max(initial=0.0)) + 1e-300  # columns that never moved the residuals
        damping = mu * np.maximum(scale, floor)
        h = cholesky_solve(a + np.diag(damping), -g)
        if math.sqrt(float(np.sum(h * h))) <= xtol * (math.sqrt(float(np.sum(x * x))) + xtol):
            status = "xtol"
            break
        x_new = x + h
        r_new = fun(x_new)
        nfev += 1
        cost_new = 0.5 * float(np.sum(r_new * r_new))
        predicted = 0.5 * float(np.sum(h * (damping * h - g)))
        gain = (cost - cost_new) / predicted if predicted > 0.0 and math.isfinite(cost_new) else -1.0
        if gain > 0.0:
            x, r, cost = x_new, r_new, cost_new
            j = jac(x)
            a = gram(j)
            g = (j * r[:, None]).sum(axis=0)
            np.maximum(scale, np.diagonal(a), out=scale)
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            nu = 2.0
        else:
            mu *= nu
            nu *= 2.0
    return LMResult(x=x, cost=cost, nfev=nfev, status=status)
