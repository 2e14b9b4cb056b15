"""Levenberg-Marquardt for small dense least-squares problems, the same bits on every machine.

TEB's band optimisation (`teb.py`) minimises 1/2 |r(x)|^2 over about 40 variables, a few
hundred times per episode, and every later tick starts from the band it returned: a
last-bit difference in one step becomes a different episode. So the solver may use only
arithmetic whose result is fixed by the code, not by the machine:

- scipy's `least_squares(method="lm")` runs MINPACK, whose C translation in scipy 1.15-1.17
  reads one element past the Jacobian when `qrfac` recomputes a column norm (valgrind shows
  it), so a step could depend on whatever the heap holds there;
- `numpy.linalg` and `@` run on OpenBLAS (or another BLAS), whose kernels, chosen by CPU
  type and thread count, sum in different orders.

The normal equations are formed and solved by MuJoCo's own linear algebra
(`mju_mulMatTMat`, `mju_mulMatTVec`, `mju_cholFactor`, `mju_cholSolve`): plain C loops in a
fixed order and no threads, in the one library binary whose physics every episode
already rests on (a machine where MuJoCo rounds differently steps differently anyway).
They replaced a Cholesky factorisation written in numpy column by column (the same bits
on every CPU too, but 45 times slower: 210 against 4.6 us for 41 variables, most of
TEB's time per tick). The algorithm is Marquardt's, as in Madsen, Nielsen and Tingleff
(2004), "Methods for non-linear least squares problems", Algorithm 3.16: damping
mu * diag(scale) with `scale` the largest diagonal of J^T J seen so far (MINPACK's
internal scaling), mu updated from the gain ratio (Nielsen's rule).

MuJoCo is imported when the solver first runs, not with the module: importing a planner
loads no simulator (tests/test_robot.py checks every shipped planner and behaviour).
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
    """J^T J (n, n) for J (m, n), by MuJoCo's `mju_mulMatTMat`."""
    import mujoco

    j = np.ascontiguousarray(j, dtype=np.float64)
    a = np.empty((j.shape[1], j.shape[1]))
    mujoco.mju_mulMatTMat(a, j, j)
    return a


def gradient(j: np.ndarray, r: np.ndarray) -> np.ndarray:
    """J^T r (n,), by MuJoCo's `mju_mulMatTVec`."""
    import mujoco

    g = np.empty(j.shape[1])
    mujoco.mju_mulMatTVec(g, np.ascontiguousarray(j, dtype=np.float64), np.ascontiguousarray(r, dtype=np.float64))
    return g


def cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with a x = b for a symmetric positive definite (n, n), by MuJoCo's Cholesky
    factorisation; a is not modified. A pivot that is not positive is taken as 1e-300 (the
    damped systems of `minimise` have none)."""
    import mujoco

    factor = np.array(a, dtype=np.float64, order="C")
    mujoco.mju_cholFactor(factor, 1e-300)
    x = np.empty(len(b))
    mujoco.mju_cholSolve(x, factor, np.ascontiguousarray(b, dtype=np.float64))
    return x


Evaluation = tuple[np.ndarray, Callable[[], np.ndarray]]
"""The residuals r(x) (m,) and what gives the Jacobian there (m, n) when it is needed."""


def levenberg_marquardt(
    fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, **options
) -> LMResult:
    """Minimise 1/2 |fun(x)|^2 from x0, with the Jacobian `jac(x)` (m, n): `minimise` (and
    its options) with the two given apart."""
    return minimise(lambda x: (fun(x), lambda: jac(x)), x0, **options)


def minimise(
    evaluate: Callable[[np.ndarray], Evaluation],
    x0: np.ndarray,
    *,
    max_nfev: int,
    mu0: float = 1e-3,
    gtol: float = 1e-8,
    xtol: float = 1e-8,
) -> LMResult:
    """Minimise 1/2 |r(x)|^2 from x0, where `evaluate(x)` gives r(x) and the Jacobian's
    maker: a caller that gets both from one batched evaluation pays for one, and the
    Jacobian is made only at the points the search keeps.

    Stops when the gradient's largest component is at most `gtol`, when a step is shorter
    than `xtol` (|x| + xtol), or after `max_nfev` residual evaluations."""
    x = np.array(x0, dtype=np.float64)
    r, jacobian = evaluate(x)
    nfev = 1
    cost = 0.5 * float(np.sum(r * r))
    j = jacobian()
    a = gram(j)
    g = gradient(j, r)
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
        r_new, jacobian = evaluate(x_new)
        nfev += 1
        cost_new = 0.5 * float(np.sum(r_new * r_new))
        predicted = 0.5 * float(np.sum(h * (damping * h - g)))
        gain = (cost - cost_new) / predicted if predicted > 0.0 and math.isfinite(cost_new) else -1.0
        if gain > 0.0:
            x, r, cost = x_new, r_new, cost_new
            j = jacobian()
            a = gram(j)
            g = gradient(j, r)
            np.maximum(scale, np.diagonal(a), out=scale)
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            nu = 2.0
        else:
            mu *= nu
            nu *= 2.0
    return LMResult(x=x, cost=cost, nfev=nfev, status=status)
