import numpy as np
import pytest

from dynabarn.worlds.profiles import PROFILE_SETS, WaypointScheme
from dynabarn.worlds.trajectory import edge_crossings, generate_trajectory, newton_coefficients, newton_eval


def test_newton_polynomial_interpolates_its_points():
    xs = np.array([-7.0, -2.0, 3.0, 9.0])
    ys = np.array([4.0, -6.0, 1.0, 10.0])
    c = newton_coefficients(xs, ys)
    np.testing.assert_allclose(newton_eval(xs, c, xs), ys, atol=1e-12)
    np.testing.assert_allclose(newton_eval(xs, c, [0.5]), np.polyval(np.polyfit(xs, ys, 3), [0.5]), atol=1e-9)


def test_edge_crossings_of_a_line():
    xs = np.array([0.0, 5.0])
    c = newton_coefficients(xs, [0.0, 10.0])  # y = 2x: crosses y=10 at x=5, y=-10 at x=-5
    x, y = edge_crossings(xs, c)
    order = np.argsort(x)
    np.testing.assert_allclose(x[order], [-5.0, 5.0], atol=1e-9)
    np.testing.assert_array_equal(y[order], [-10.0, 10.0])


@pytest.mark.parametrize("set_name", ["table1", "release2022"])
def test_trajectories_obey_their_profile(set_name):
    ps = PROFILE_SETS[set_name]
    rng = np.random.default_rng(7)
    for profile in (*ps.easy_motion, *ps.hard_motion):
        for _ in range(150):
            tr = generate_trajectory(rng, profile, scheme=ps.waypoints)
            assert tr.times[0] == 0.0
            assert np.all(np.diff(tr.times) > 0)
            assert np.all(np.abs(tr.xy) <= 10.0)
            assert np.max(np.abs(tr.xy[0])) == 10.0, "starts on the arena border"
            assert np.max(np.abs(tr.xy[-1])) == 10.0, "ends on the arena border"
            dx = np.diff(tr.xy[:, 0])
            assert np.all(dx > 0) or np.all(dx < 0), "sorted by x"
            lo, hi = profile.speed
            # Positions and times are stored to 1 mm / 1 ms: allow that rounding.
            tol = 0.01 * hi + 2e-3 / np.diff(tr.times).min()
            s = tr.segment_speeds()
            assert np.all(s >= lo - tol) and np.all(s <= hi + tol)
            assert profile.order[0] <= tr.order <= profile.order[1]


def test_integer_scheme_puts_waypoints_on_integer_x_or_the_border():
    rng = np.random.default_rng(3)
    tr = generate_trajectory(rng, PROFILE_SETS["table1"].hard_motion[0], scheme=WaypointScheme.INTEGER)
    x, y = tr.xy.T
    on_grid = np.isclose(x, np.round(x))
    on_border = np.isclose(np.abs(y), 10.0)
    assert np.all(on_grid | on_border)


def test_release_scheme_uses_linspace_x():
    rng = np.random.default_rng(3)
    tr = generate_trajectory(rng, PROFILE_SETS["release2022"].easy_motion[0], scheme=WaypointScheme.RELEASE)
    x, y = tr.xy.T
    lin = np.round(np.linspace(-10, 10, 10), 3)
    ok = np.isin(np.round(x, 3), lin) | np.isclose(x, np.round(x)) | np.isclose(np.abs(y), 10)
    assert np.all(ok)


def test_same_generator_state_same_trajectory():
    p = PROFILE_SETS["table1"].hard_motion[0]
    a = generate_trajectory(np.random.default_rng(11), p)
    b = generate_trajectory(np.random.default_rng(11), p)
    c = generate_trajectory(np.random.default_rng(12), p)
    assert a == b and a != c
