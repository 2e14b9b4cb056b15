"""TEB's optimiser: known minima, the normal equations' solution, and no BLAS on its path."""

from __future__ import annotations

import numpy as np
import pytest

from dynabarn.planners.levenberg_marquardt import cholesky_solve, gram, levenberg_marquardt


def test_cholesky_solve_matches_lapack_on_spd_systems():
    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 41):
        m = rng.normal(size=(n + 5, n))
        a = m.T @ m + 0.1 * np.eye(n)
        b = rng.normal(size=n)
        x = cholesky_solve(a, b)
        assert np.allclose(x, np.linalg.solve(a, b), rtol=1e-9, atol=1e-12)
        assert np.allclose(gram(m), m.T @ m, rtol=1e-12, atol=1e-12)


def test_rosenbrock_minimum_is_found():
    def fun(p):
        return np.array([10.0 * (p[1] - p[0] ** 2), 1.0 - p[0]])

    def jac(p):
        return np.array([[-20.0 * p[0], 10.0], [-1.0, 0.0]])

    sol = levenberg_marquardt(fun, jac, np.array([-1.2, 1.0]), max_nfev=200)
    assert np.allclose(sol.x, [1.0, 1.0], atol=1e-6)
    assert sol.cost < 1e-12
    assert sol.status in ("gtol", "xtol")
    assert sol.nfev < 200


def test_linear_least_squares_lands_on_the_normal_equations_solution():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(30, 6))
    b = rng.normal(size=30)
    sol = levenberg_marquardt(lambda x: a @ x - b, lambda x: a, np.zeros(6), max_nfev=50)
    assert np.allclose(sol.x, np.linalg.lstsq(a, b, rcond=None)[0], atol=1e-7)


def test_max_nfev_bounds_the_residual_evaluations():
    calls = []

    def fun(p):
        calls.append(1)
        return np.array([10.0 * (p[1] - p[0] ** 2), 1.0 - p[0]])

    sol = levenberg_marquardt(
        fun, lambda p: np.array([[-20.0 * p[0], 10.0], [-1.0, 0.0]]), np.array([-1.2, 1.0]), max_nfev=5
    )
    assert len(calls) == sol.nfev <= 5
    assert sol.status == "max_nfev"


def test_a_variable_that_moves_nothing_stays_put():
    # The third variable never enters the residuals: its column is zero, its step must be 0.
    def fun(p):
        return np.array([p[0] - 1.0, p[1] + 2.0, p[0] + p[1]])

    def jac(p):
        return np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])

    sol = levenberg_marquardt(fun, jac, np.array([0.0, 0.0, 5.0]), max_nfev=30)
    assert sol.x[2] == 5.0
    assert np.all(np.isfinite(sol.x))


def test_no_blas_call_on_the_optimisers_path(monkeypatch):
    """np.dot / matmul route to OpenBLAS, whose kernels differ between CPUs."""
    import numpy

    def refuse(*args, **kwargs):
        raise AssertionError("BLAS call on the optimiser's path")

    for name in ("dot", "matmul", "vdot", "inner", "einsum"):
        monkeypatch.setattr(numpy, name, refuse)
    monkeypatch.setattr(numpy.linalg, "solve", refuse)
    rng = np.random.default_rng(1)
    a = rng.normal(size=(12, 4))
    b = rng.normal(size=12)
    sol = levenberg_marquardt(lambda x: (a * x).sum(axis=1) - b, lambda x: a, np.zeros(4), max_nfev=20)
    assert np.all(np.isfinite(sol.x))


@pytest.mark.parametrize("seed", [0, 1])
def test_teb_episode_twice_in_one_process_is_identical(seed):
    """The optimiser keeps no state between calls: the same episode twice gives the same result."""
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol
    from dynabarn.provenance import SHIPPED_WORLDS
    from dynabarn.sim import run_episode

    world = SHIPPED_WORLDS / "world_205.xml"
    runs = [run_episode(world, get_planner("teb"), get_protocol("barn"), seed=seed) for _ in range(2)]
    a, b = (r.to_dict() for r in runs)
    for key in ("outcome", "n_ticks", "path_length", "time", "mean_abs_jerk"):
        assert a[key] == b[key], key


def test_the_normal_equations_are_exact_where_the_arithmetic_is():
    """J^T J and J^T r by MuJoCo's loops: exact on small whole numbers (every product and sum
    representable), whatever the Jacobian's memory layout, and a solve lands on the
    integer solution it was built from."""
    from dynabarn.planners.levenberg_marquardt import gradient

    rng = np.random.default_rng(5)
    for m, n in ((3, 1), (95, 41), (12, 7)):
        j = rng.integers(-9, 10, size=(m, n)).astype(float)
        r = rng.integers(-9, 10, size=m).astype(float)
        expected = (j[:, :, None] * j[:, None, :]).sum(axis=0)
        for layout in (j, np.asfortranarray(j), j[::-1].copy()[::-1]):
            assert np.array_equal(gram(layout), expected)
            assert np.array_equal(gradient(layout, r), (j * r[:, None]).sum(axis=0))
        a = expected + n * np.eye(n)
        x = rng.integers(-5, 6, size=n).astype(float)
        assert np.allclose(cholesky_solve(a, (a * x).sum(axis=1)), x, rtol=0, atol=1e-9)


@pytest.mark.parametrize("planner", ["teb", "teb@teb_dynamic"])
def test_teb_steps_variables_together_with_the_bits_of_one_row_per_variable(planner):
    """The coloured forward differences give every Jacobian of an episode bit for bit as one
    batch row per variable did, and the colouring needs far fewer rows."""
    from dynabarn.planners import get_planner, planner_spec
    from dynabarn.planners.teb import TEBPlanner
    from dynabarn.protocol import get_protocol
    from dynabarn.provenance import SHIPPED_WORLDS
    from dynabarn.sim import run_episode

    name, config, _ = planner_spec(planner)
    teb = get_planner(name, **config)
    compared = []

    def checked(z, start, goal, obstacles, moving):
        r, jacobian = TEBPlanner._evaluate(teb, z, start, goal, obstacles, moving)
        if len(compared) < 60:
            h = 1e-6 * np.maximum(1.0, np.abs(z))
            rows = teb._residuals(np.vstack([z[None], z[None, :] + np.diag(h)]), start, goal, obstacles, moving)
            assert np.array_equal(r.view(np.int64), rows[0].view(np.int64))
            expected = ((rows[1:] - rows[0]) / h[:, None]).T
            assert np.array_equal(jacobian().view(np.int64), expected.view(np.int64))
            compared.append(max(c.n_colours for c in teb._colourings.values()))
        return r, jacobian

    teb._evaluate = checked
    run_episode(SHIPPED_WORLDS / "world_155.xml", teb, get_protocol("barn"), seed=0)
    assert len(compared) == 60
    assert max(compared) <= 20 < 3 * (teb.cfg.n_poses - 2) + teb.cfg.n_poses - 1
