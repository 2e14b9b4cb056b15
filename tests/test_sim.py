"""The episode loop against known answers, with real MuJoCo worlds."""

import math

import numpy as np
import pytest

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import EpisodeObserver, Planner
from dynabarn.metrics import Outcome
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import MACHINE_FIELDS
from dynabarn.sim import SimConfig, run_episode
from dynabarn.worldset import resolve_world
from tests.helpers import crafted_world, obstacle

BARN = get_protocol("barn")
PAPER = get_protocol("paper2022")
HALF_LENGTH = 0.254


@pytest.fixture(scope="module")
def empty_world(tmp_path_factory):
    return crafted_world(tmp_path_factory.mktemp("w") / "empty.xml")


@pytest.fixture(scope="module")
def blocked_world(tmp_path_factory):
    # One cylinder parked on the straight line at x = 0 for the whole episode.
    return crafted_world(
        tmp_path_factory.mktemp("w") / "blocked.xml", [obstacle("obstacle_000", [[0, 0, 0], [1000, 0, 0]])]
    )


def test_straight_in_empty_world_takes_the_time_the_speed_limit_implies(empty_world):
    r = run_episode(empty_world, get_planner("straight"), BARN, seed=0)
    assert r.outcome is Outcome.SUCCESS
    # 20 m to the goal, success 1 m before it, clock from the first 0.1 m, 2 m/s top speed.
    expected = (20.0 - 1.0 - 0.1) / 2.0
    assert r.time == pytest.approx(expected, abs=0.05)
    assert r.path_length == pytest.approx(19.0, abs=0.02)
    assert r.spl == pytest.approx(1.0, abs=1e-3)
    assert r.score == pytest.approx(10.0 / 20.0)  # AT clipped up to 2 OT
    assert math.isinf(r.min_clearance)


def test_obstacle_on_the_path_collides_at_the_expected_time(blocked_world):
    r = run_episode(blocked_world, get_planner("straight"), BARN, seed=0)
    assert r.outcome is Outcome.COLLISION and r.reason == "hit obstacle_000"
    # The bumper (0.254 m ahead of the centre) meets the cylinder (r 0.5) at x = 0.754.
    travel = 11.0 - (0.5 + HALF_LENGTH)
    assert r.sim_time == pytest.approx(travel / 2.0, abs=0.06)
    assert r.min_clearance <= 0.01


def test_a_planner_that_never_moves_times_out(empty_world):
    r = run_episode(empty_world, get_planner("stop"), BARN, seed=0)
    assert r.outcome is Outcome.TIMEOUT
    assert r.sim_time == pytest.approx(BARN.time_limit)
    assert r.path_length == 0.0 and r.score == 0.0
    assert r.time_stalled == pytest.approx(BARN.time_limit, abs=0.11)


class StopShort(Planner):
    """Drive at the goal and stop 0.6 m before it."""

    name = "stop_short"

    def act(self, obs):
        gx, gy = obs.goal_in_robot
        d = math.hypot(gx, gy)
        return (min(1.0, max(0.0, d - 0.6)), 2.0 * math.atan2(gy, gx))


def test_protocols_judge_the_same_trajectory_differently(empty_world):
    barn = run_episode(empty_world, StopShort(), BARN, seed=0)
    paper = run_episode(empty_world, StopShort(), PAPER, seed=0)
    assert barn.outcome is Outcome.SUCCESS  # inside the 1 m disc
    assert paper.outcome is Outcome.TIMEOUT  # never inside the 0.3 m square
    # paper2022 starts 1 m further away and its clock runs from the start.
    assert paper.path_length > barn.path_length + 0.9


def test_same_seed_same_result_different_seed_differs():
    world = resolve_world(137)
    a = run_episode(world, get_planner("straight"), BARN, seed=4).to_dict()
    b = run_episode(world, get_planner("straight"), BARN, seed=4).to_dict()
    c = run_episode(world, get_planner("straight"), BARN, seed=5).to_dict()
    wall = MACHINE_FIELDS
    strip = lambda d: {k: v for k, v in d.items() if k not in wall}  # noqa: E731
    assert strip(a) == strip(b)
    assert a["clock_offset"] != c["clock_offset"]
    assert strip(a) != strip(c)


class Raises(Planner):
    name = "raises"

    def act(self, obs):
        if obs.time > 0.5:
            raise RuntimeError("boom")
        return 1.0, 0.0


class ReturnsNaN(Planner):
    name = "nan"

    def act(self, obs):
        return float("nan"), 0.0


def test_planner_errors_become_outcome_error(empty_world):
    r = run_episode(empty_world, Raises(), BARN)
    assert r.outcome is Outcome.ERROR and "RuntimeError: boom" in r.reason
    r = run_episode(empty_world, ReturnsNaN(), BARN)
    assert r.outcome is Outcome.ERROR and "non-finite" in r.reason


def test_command_limits_are_applied(empty_world):
    class TooFast(Planner):
        name = "too_fast"

        def act(self, obs):
            return 10.0, 0.0

    seen = []

    class Spy(EpisodeObserver):
        def on_start(self, s): ...
        def on_tick(self, t):
            seen.append(t.command.copy())

        def on_poses(self, t, p): ...
        def on_end(self, r): ...

    run_episode(empty_world, TooFast(), BARN, observers=[Spy()])
    assert max(c[0] for c in seen) == pytest.approx(2.0)


def test_bad_config_is_rejected():
    with pytest.raises(DynabarnError, match=r"in \[0\.0001, 0\.01\]"):
        SimConfig(dt=0.05)
    with pytest.raises(DynabarnError, match="whole number"):
        SimConfig(dt=0.005, control_rate=7.0)


def test_laser_sees_a_parked_obstacle(blocked_world):
    scans = []

    class Spy(EpisodeObserver):
        def on_start(self, s): ...
        def on_tick(self, t):
            scans.append(t.scan)

        def on_poses(self, t, p): ...
        def on_end(self, r): ...

    run_episode(blocked_world, get_planner("stop"), BARN, observers=[Spy()], config=SimConfig(control_rate=10))
    ahead = scans[0][359:361].mean()
    # Laser at x = 11 - 0.12 facing -x; the cylinder's surface at x = 0.5.
    assert ahead == pytest.approx(11.0 - 0.12 - 0.5, abs=0.01)
    assert np.all(scans[0] >= 0.1) and np.all(scans[0] <= 30.0)


def test_single_pose_clearance_matches_batched():
    from dynabarn.metrics import footprint_clearance, footprint_clearance_at

    rng = np.random.default_rng(0)
    for _ in range(50):
        pose = rng.uniform([-5, -5, -np.pi], [5, 5, np.pi])
        xy = rng.uniform(-6, 6, (7, 2))
        radii = rng.uniform(0.2, 0.8, 7)
        a = footprint_clearance(pose[None], xy[None], radii, (0.254, 0.215))[0]
        b = footprint_clearance_at(*pose, xy, radii, (0.254, 0.215))
        assert a == pytest.approx(b, abs=1e-12)
    # A known case: obstacle 1 m ahead of the bumper, robot facing +x.
    assert footprint_clearance_at(0, 0, 0, np.array([[1.754, 0.0]]), np.array([0.5]), (0.254, 0.215)) == pytest.approx(
        1.0
    )


def test_single_pose_clearance_has_the_array_forms_bits():
    """The per-tick clearance on Python floats equals numpy's elementwise form bit for bit
    (recordings carry it): random poses, obstacles touching the footprint's sides, ties."""
    from dynabarn.metrics import footprint_clearance_at

    def array_form(x, y, yaw, xy, radii, half):
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = xy[:, 0] - x, xy[:, 1] - y
        ox = np.maximum(np.abs(c * dx + s * dy) - half[0], 0.0)
        oy = np.maximum(np.abs(c * dy - s * dx) - half[1], 0.0)
        return float((np.hypot(ox, oy) - radii).min())

    rng = np.random.default_rng(7)
    for i in range(20_000):
        n = int(rng.integers(1, 20))
        pose = rng.uniform([-10, -10, -4], [10, 10, 4])
        xy = rng.uniform(-10, 10, (n, 2))
        if i % 3 == 0:  # beside the footprint: one of the two offsets is 0
            xy[:, 0] = pose[0] + rng.uniform(-0.4, 0.4, n)
        if i % 5 == 0 and n > 1:  # two obstacles at the same distance
            xy[1] = xy[0]
        radii = rng.uniform(0.05, 0.8, n)
        expected = array_form(*pose, xy, radii, (0.254, 0.215))
        assert footprint_clearance_at(*pose, xy, radii, (0.254, 0.215)) == expected
