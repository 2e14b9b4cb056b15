import numpy as np

from dynabarn.mjcf import read_world
from dynabarn.provenance import SHIPPED_WORLDS
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import EndBehavior, Interpolation, Obstacle, WorldSpec
from dynabarn.worlds.trajectory import Trajectory


def _world(interp, end, xy, times):
    tr = Trajectory(times=np.asarray(times, float), xy=np.asarray(xy, float), profile="t")
    return WorldSpec(
        name="t",
        world_id=None,
        difficulty="easy",
        obstacles=(Obstacle("obstacle_000", tr),),
        interpolation=interp,
        end_behavior=end,
    )


def test_linear_playback_hits_keyframes_and_midpoints():
    w = _world(Interpolation.LINEAR, EndBehavior.HOLD, [[10, 0], [0, 0], [0, 5]], [0, 10, 15])
    p = SchedulePlayer(w)
    np.testing.assert_allclose(p.state(5.0)[0][0], [5, 0])
    np.testing.assert_allclose(p.state(5.0)[1][0], [-1, 0])
    np.testing.assert_allclose(p.state(12.5)[0][0], [0, 2.5])
    np.testing.assert_allclose(p.state(100.0)[0][0], [0, 5])  # hold


def test_loop_wraps_at_duration_and_offset_shifts_clock():
    w = _world(Interpolation.LINEAR, EndBehavior.LOOP, [[10, 0], [0, 0]], [0, 10])
    p = SchedulePlayer(w)
    np.testing.assert_allclose(p.state(10.0)[0][0], [10, 0])  # wrapped to the first keyframe
    np.testing.assert_allclose(p.state(13.0)[0][0], [7, 0])
    q = SchedulePlayer(w, clock_offset=3.0)
    np.testing.assert_allclose(q.state(0.0)[0][0], [7, 0])


def test_spline_passes_keyframes_and_velocity_is_derivative():
    w = read_world(SHIPPED_WORLDS / "world_250.xml")
    w = WorldSpec.from_dict({**w.to_dict(), "interpolation": "spline"})
    p = SchedulePlayer(w)
    for i, o in enumerate(w.obstacles):
        for t, xy in zip(o.trajectory.times[:-1], o.trajectory.xy[:-1], strict=True):
            np.testing.assert_allclose(p.state(t)[0][i], xy, atol=1e-9)
    for t in np.linspace(0.3, 30, 25):
        h = 1e-5
        num = (p.state(t + h)[0] - p.state(t - h)[0]) / (2 * h)
        np.testing.assert_allclose(p.state(t)[1], num, atol=1e-4)


def test_linear_velocity_matches_numerical_derivative():
    w = read_world(SHIPPED_WORLDS / "world_210.xml")
    p = SchedulePlayer(w)
    for t in np.linspace(0.37, 40, 30):
        h = 1e-6
        num = (p.state(t + h)[0] - p.state(t - h)[0]) / (2 * h)
        np.testing.assert_allclose(p.state(t)[1], num, atol=1e-3)


def test_positions_into_reuses_buffers():
    w = read_world(SHIPPED_WORLDS / "world_210.xml")
    p = SchedulePlayer(w)
    pos = np.zeros((p.n_obstacles, 2))
    vel = np.zeros((p.n_obstacles, 2))
    p.positions_into(3.0, pos, vel)
    ref_pos, ref_vel = p.state(3.0)
    np.testing.assert_array_equal(pos, ref_pos)
    np.testing.assert_array_equal(vel, ref_vel)
