"""base_local_planner's TrajectoryPlanner (`trajectory_planner`): its rollouts, its way of
waiting (stop and turn, not back up), its escape, and episodes in real MuJoCo worlds."""

import math

import numpy as np
import pytest

from dynabarn.interfaces import EpisodeInfo, Observation
from dynabarn.metrics import Outcome
from dynabarn.planners import get_planner, read_planner_config
from dynabarn.planners.dwa import rollout
from dynabarn.planners.trajectory_planner import ramped_rollout
from dynabarn.protocol import get_protocol
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world

ANGLES = np.linspace(-2.35619, 2.35619, 720)
# A corridor's walls far away, the goal 15 m ahead of a robot at the origin facing +x.
WALLS = np.array([[-12, 0, 0.5, 30], [18, 0, 0.5, 30], [3, 12, 30, 0.5], [3, -12, 30, 0.5]], dtype=float)


def _info() -> EpisodeInfo:
    return EpisodeInfo(
        laser_angles=ANGLES,
        laser_offset=np.array([0.12, 0.0]),
        laser_range=(0.1, 30.0),
        control_period=0.1,
        v_limits=(-2.0, 2.0),
        w_max=3.14,
        accel_limits=(10.0, 20.0),
        footprint=(0.508, 0.43),
        walls=WALLS,
        goal=np.array([15.0, 0.0]),
        goal_tolerance=1.0,
    )


def _observe(scan: np.ndarray, velocity=(0.0, 0.0), pose=(0.0, 0.0, 0.0)) -> Observation:
    pose = np.array(pose, dtype=float)
    goal = np.array([15.0, 0.0])
    return Observation(0.0, scan, pose, np.array(velocity, dtype=float), goal - pose[:2], goal)


def _walls_around(ahead: float, side: float = 30.0) -> np.ndarray:
    """The ranges of a wall `ahead` metres in front of the laser, across the robot's way, and
    of two walls `side` metres to its left and right (a dead end, open behind)."""
    cos, sin = np.cos(ANGLES), np.sin(ANGLES)
    with np.errstate(divide="ignore"):
        front = np.where(cos > 1e-9, ahead / cos, np.inf)
        sides = np.where(np.abs(sin) > 1e-9, side / np.abs(sin), np.inf)
    return np.minimum(np.minimum(front, sides), 30.0)


def test_ramped_rollouts_start_at_the_pose_and_respect_the_acceleration_limits():
    pose = np.array([1.0, -2.0, 0.3])
    v = np.array([2.0, 0.0, 1.0])
    w = np.array([0.0, 1.5, -3.0])
    traj = ramped_rollout(pose, 1.0, 0.5, v, w, (2.5, 5.0), 0.1, 21)
    assert traj.shape == (3, 21, 3)
    np.testing.assert_array_equal(traj[:, 0], np.broadcast_to(pose, (3, 3)))
    speed = np.hypot(*np.diff(traj[..., :2], axis=1).transpose(2, 0, 1)) / 0.1
    turn = np.diff(traj[..., 2], axis=1) / 0.1
    assert np.all(np.abs(np.diff(speed, axis=1)) <= 2.5 * 0.1 + 1e-9)  # never faster than acc x dt
    assert np.all(np.abs(np.diff(turn, axis=1)) <= 5.0 * 0.1 + 1e-9)
    assert speed[0, 0] == pytest.approx(1.25) and speed[0, -1] == pytest.approx(2.0)  # reaches its sample
    assert speed[1, -1] == pytest.approx(0.0, abs=1e-12) and turn[2, -1] == pytest.approx(-3.0)


def test_a_ramp_already_at_its_speed_is_the_constant_velocity_arc():
    """At its sample speed from the start, a ramped rollout is the arc (to Euler's error)."""
    pose = np.array([0.0, 0.0, 0.0])
    v, w = np.array([1.0]), np.array([0.5])
    ramp = ramped_rollout(pose, 1.0, 0.5, v, w, (2.5, 5.0), 0.01, 101)
    arc = rollout(pose, v, w, np.array([1.0]))
    np.testing.assert_allclose(ramp[0, -1, :2], arc[0, -1, :2], atol=0.01)


def test_a_blocked_way_stops_and_turns():
    """A dead end (a wall 0.9 m ahead, walls 0.7 m to each side) blocks every forward sample
    the window allows at 1 m/s, not the robot's place: move_base's TrajectoryPlanner then
    stops and turns in place, and without its rotations it backs up."""
    cfg = read_planner_config("dwa_dynabarn_authors")
    scan = _walls_around(0.9, 0.7)
    tp = get_planner("trajectory_planner", **cfg)
    tp.reset(_info())
    v, w = tp.act(_observe(scan, velocity=(1.0, 0.0)))
    assert v == 0.0 and abs(w) >= tp.cfg.min_in_place_vel_theta
    no_turning = get_planner("trajectory_planner", **cfg, rotate_in_place=False)
    no_turning.reset(_info())
    assert no_turning.act(_observe(scan, velocity=(1.0, 0.0))) == (cfg["escape_vel"], 0.0)


def test_an_open_way_goes_ahead_and_slows_near_the_goal():
    cfg = read_planner_config("dwa_dynabarn_authors")
    tp = get_planner("trajectory_planner", **cfg)
    tp.reset(_info())
    v, w = tp.act(_observe(np.full(720, 30.0), velocity=(1.0, 0.0)))
    assert v == pytest.approx(1.5) and w == pytest.approx(0.0, abs=0.1)  # the window's top: 1 + 10 x 0.05
    near = _observe(np.full(720, 30.0), velocity=(1.0, 0.0), pose=(14.0, 0.0, 0.0))
    v, _ = tp.act(near)
    assert v <= 1.0 / tp.cfg.sim_time + 1e-9  # 1 m from the goal, 2 s horizon: 0.5 m/s at most


def test_escape_stops_when_its_own_place_is_blocked():
    cfg = read_planner_config("dwa_dynabarn_authors")
    tp = get_planner("trajectory_planner", **cfg)
    tp.reset(_info())
    assert tp.act(_observe(_walls_around(0.05), velocity=(0.5, 0.0))) == (0.0, 0.0)


def test_it_drives_real_worlds_and_is_deterministic():
    barn = get_protocol("barn")
    cfg = read_planner_config("dwa_dynabarn_authors")
    r = run_episode(resolve_world(137), get_planner("trajectory_planner", **cfg), barn, seed=0)
    assert r.outcome is Outcome.SUCCESS, r.summary()
    again = run_episode(resolve_world(137), get_planner("trajectory_planner", **cfg), barn, seed=0)
    assert (again.time, again.path_length, again.min_clearance) == (r.time, r.path_length, r.min_clearance)
    assert math.isfinite(r.spl) and r.spl > 0.9


def test_escaping_lasts_until_the_robot_has_moved_away():
    """Once backing up, only rotations are sampled until the robot moved escape_reset_dist."""
    cfg = read_planner_config("dwa_dynabarn_authors")
    tp = get_planner("trajectory_planner", **cfg, rotate_in_place=False)
    tp.reset(_info())
    assert tp.act(_observe(_walls_around(0.9, 0.7), velocity=(1.0, 0.0)))[0] == cfg["escape_vel"]
    open_way = np.full(720, 30.0)
    assert tp.act(_observe(open_way, velocity=(-0.5, 0.0)))[0] == cfg["escape_vel"]  # still escaping
    moved = _observe(open_way, velocity=(-0.5, 0.0), pose=(-0.2, 0.0, 0.0))  # 0.2 m back: this tick ends it
    assert tp.act(moved)[0] == cfg["escape_vel"]
    assert tp.act(moved)[0] > 0.0


def test_the_ablation_variants_are_valid_configurations():
    """Each variant `benchmarks/dwa_ablation.py` sweeps builds its planner; each switch it
    turns off is one of the planner's, so a renamed switch cannot drop out of the table."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from dwa_ablation import VARIANTS

    base = read_planner_config("dwa_dynabarn_authors")
    switches = {"ramp", "score_at_end", "rotate_in_place", "ros_escape", "slow_near_goal", "sim_period"}
    off = set()
    for planner, overrides, _ in VARIANTS.values():
        if planner == "ros":
            continue
        built = get_planner(planner, **(base | overrides))
        assert all(getattr(built.cfg, k) == v for k, v in overrides.items())
        off |= set(overrides) & switches
    assert off == switches
