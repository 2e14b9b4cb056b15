"""The known map as the laser would see it (`MapScan`) and the student's map input
(`FeatureConfig.static_map`, issue 57): the closed form against MuJoCo's own ray casting,
and inputs that follow the map."""

from __future__ import annotations

import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from dynabarn.interfaces import Observation
from dynabarn.mjcf import write_world
from dynabarn.perception import MapScan
from dynabarn.planners.learned.features import FeatureConfig, Features
from dynabarn.protocol import get_protocol
from dynabarn.robot import LASER_GEOM_GROUPS
from dynabarn.sim import Simulation
from dynabarn.worlds.generate import generate_world
from dynabarn.worlds.profiles import STATIC_FIELDS, get_profile_set


@pytest.fixture(scope="module")
def field_world(tmp_path_factory):
    """A world of the tiers' kind (a BARN field of standing cylinders, walls), its moving
    obstacles taken out: what the laser sees there is the known map and nothing else."""
    world = generate_world(250, get_profile_set("table1"), static_field=STATIC_FIELDS["barn-grid"])
    path = tmp_path_factory.mktemp("map") / "field.xml"
    write_world(replace(world, obstacles=()), path)
    return world, Simulation(path)


def _mujoco_ranges(sim: Simulation, pose) -> np.ndarray:
    """MuJoCo's cast over every geom the laser sees, the static field's too."""
    sim.reset(pose)
    mujoco.mj_kinematics(sim.model, sim.data)
    laser = sim.laser
    a = laser.angles + pose[2]
    vec = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1).ravel()
    geomid, dist = np.zeros(laser.n, dtype=np.int32), np.zeros(laser.n)
    mujoco.mj_multiRay(
        sim.model, sim.data, sim.data.site_xpos[laser.site], vec, LASER_GEOM_GROUPS, 1,
        laser.robot_body, geomid, dist, None, laser.n, laser.params.laser_range_max,
    )  # fmt: skip
    return np.where(geomid < 0, laser.params.laser_range_max, dist)


def test_the_map_scan_equals_mujoco_ray_casting_over_walls_and_the_field(field_world):
    world, sim = field_world
    info = sim.episode_info(get_protocol("barn"), seed=0)
    map_scan = MapScan(info)
    static = np.asarray(world.layout.cylinders)
    walls_only = MapScan(replace(info, static_obstacles=static[:0]))
    rng = np.random.default_rng(3)
    poses = [
        (0.0, -9.0, math.pi / 2),
        *zip(rng.uniform(-4, 4, 15), rng.uniform(-9, 9, 15), rng.uniform(-3, 3, 15), strict=True),
    ]
    compared = walls_hit = field_hit = 0
    for pose in poses:
        reference = _mujoco_ranges(sim, pose)
        origin = sim.data.site_xpos[sim.laser.site][:2]
        if np.any(np.hypot(*(static[:, :2] - origin).T) < static[:, 2] + 1e-3):
            continue  # the laser inside a cylinder: no ray leaves it the same way twice
        ours = map_scan(np.asarray(pose))
        np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-6)
        compared += 1
        # Both parts counted: beams that end on a wall, and beams a standing cylinder stops first.
        wall = walls_only(np.asarray(pose))
        walls_hit += int(np.sum((ours == wall) & (wall < info.laser_range[1])))
        field_hit += int(np.sum(ours < wall))
    assert compared >= 10 and walls_hit > 500 and field_hit > 2000


def _features(info, pose) -> np.ndarray:
    feats = Features(FeatureConfig(history=2, static_map=True))
    feats.reset(info)
    obs = Observation(
        time=0.0, scan=np.full(len(info.laser_angles), 5.0), pose=np.asarray(pose, dtype=np.float64),
        velocity=np.zeros(2), goal_in_robot=np.array([10.0, 0.0]), goal_in_world=info.goal,
    )  # fmt: skip
    return feats(obs)


def test_the_students_map_input_changes_where_the_map_changes_and_nowhere_else(field_world):
    _, sim = field_world
    info = sim.episode_info(get_protocol("barn"), seed=0)
    cfg = FeatureConfig(history=2, static_map=True)
    lay = cfg.layout()
    a, b = lay["static_map"]
    assert (a, b) == (lay["history"][1], lay["history"][1] + lay["pooled"]) and lay["size"] == 722 + 3 * 180
    pose = (8.0, 0.0, math.pi)  # before the field, facing it: the nearest of the map ahead is 5 m off
    before = _features(info, pose)
    # The same scan, goal and pose: only the map differs, by one cylinder 2 m straight ahead.
    laser_x, laser_y = pose[0] - info.laser_offset[0], pose[1]
    extra = np.array([[laser_x - 2.0, laser_y, 0.2]])
    after = _features(replace(info, static_obstacles=np.concatenate([info.static_obstacles, extra])), pose)
    changed = np.flatnonzero(before != after)
    # The local goal may move (the global plan, on the same map, goes round the cylinder);
    # of the rest, only the map's channel changed: the scans are the same.
    changed = changed[(changed < 720) | (changed >= 722)]
    assert len(changed) > 0 and changed.min() >= a and changed.max() < b
    # The pooled beams straight ahead read the new cylinder's near face: 1.8 m, scaled by 10 m.
    ahead = a + np.argmin(np.abs(info.laser_angles[:: cfg.history_pool] + 0.0)[: b - a])
    assert after[ahead] == pytest.approx(0.18, abs=2e-3)
    # Beyond the cylinder's angular extent (atan(0.2 / 2) = 5.7 degrees) nothing moved.
    bearing = info.laser_angles.reshape(-1, cfg.history_pool).mean(axis=1)
    assert np.all(np.abs(bearing[changed - a]) < math.radians(7.0))
    # Without the option the vector has no map and does not depend on it.
    plain = FeatureConfig(history=2)
    assert plain.layout()["static_map"] is None and plain.size() == cfg.size() - lay["pooled"]


def _one_track(x: float, y: float, size: float):
    from dynabarn.perception import Tracks

    one, z = np.ones(1), np.zeros((1, 2))
    return Tracks(0.0, np.zeros(1, dtype=np.int64), np.array([[x, y]]), z, size * one, z, z, z, one, one)


def test_unexplained_returns_are_the_ones_neither_the_map_nor_a_track_explains(field_world):
    """What `predictive`'s scan guard plans against: a scan of the known map alone leaves
    nothing; an obstacle 2 m ahead that no track holds leaves its near face, one point per
    4 beams; a track around it explains it."""
    from dynabarn.perception import Tracks
    from dynabarn.perception.unexplained import UnexplainedReturns

    _, sim = field_world
    info = sim.episode_info(get_protocol("barn"), seed=0)
    unexplained = UnexplainedReturns(info)
    pose = np.array([8.0, 0.0, math.pi])
    the_map = np.minimum(MapScan(info)(pose), info.laser_range[1])
    obs = Observation(
        time=0.0, scan=the_map, pose=pose, velocity=np.zeros(2), goal_in_robot=np.zeros(2), goal_in_world=info.goal
    )
    assert len(unexplained(obs, Tracks.empty())) == 0
    # A box's face 2 m ahead of the laser, 0.4 m wide: about +-5.7 degrees of beams.
    face = np.abs(info.laser_angles) < math.atan(0.2 / 2.0)
    scan = the_map.copy()
    scan[face] = 2.0 / np.cos(info.laser_angles[face])
    obs = Observation(
        time=0.0, scan=scan, pose=pose, velocity=np.zeros(2), goal_in_robot=np.zeros(2), goal_in_world=info.goal
    )
    points = unexplained(obs, Tracks.empty())
    laser_x = pose[0] - info.laser_offset[0]
    assert len(points) == pytest.approx(face.sum() / 4, abs=2)
    np.testing.assert_allclose(points[:, 0], laser_x - 2.0, atol=1e-9)
    assert np.abs(points[:, 1]).max() <= 0.2 + 1e-9
    assert len(unexplained(obs, _one_track(laser_x - 2.1, 0.0, 0.25))) == 0
    # A track elsewhere explains nothing here.
    assert len(unexplained(obs, _one_track(laser_x - 2.1, 3.0, 0.25))) == len(points)
