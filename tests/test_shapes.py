"""Obstacle shapes: boxes and capsules beside cylinders, in MJCF, the scan, contacts and clearance."""

import math

import mujoco
import numpy as np
import pytest

from dynabarn.errors import WorldError
from dynabarn.metrics import Outcome, footprint_clearance, shape_clearance
from dynabarn.mjcf import load_model, read_world, write_world
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder, obstacle_track, read_recording
from dynabarn.robot import JACKAL
from dynabarn.sim import Episode, Simulation, run_episode
from dynabarn.worlds.generate import generate_world
from dynabarn.worlds.profiles import SHAPE_MIXES, get_profile_set
from dynabarn.worlds.spec import EndBehavior, Interpolation, Obstacle, WorldSpec
from tests.helpers import obstacle

HALF = (JACKAL.length / 2, JACKAL.width / 2)


def _parked(name: str, x: float, y: float, **shape) -> Obstacle:
    """An obstacle that stays at (x, y): a schedule that does not move."""
    o = obstacle(name, [[0, x, y], [1000, x, y]])
    return Obstacle(o.name, o.trajectory, **shape)


def _write(path, obstacles, name="shapes"):
    world = WorldSpec(
        name=name,
        world_id=None,
        difficulty="easy",
        obstacles=tuple(obstacles),
        interpolation=Interpolation.LINEAR,
        end_behavior=EndBehavior.HOLD,
    )
    write_world(world, path)
    return path


BOX = {"shape": "box", "radius": 0.0, "half_length": 0.4, "half_width": 0.25, "yaw": 0.3}
CAPSULE = {"shape": "capsule", "radius": 0.35, "half_length": 0.6, "yaw": 1.1}


def test_shapes_round_trip_and_compile_to_the_right_geoms(tmp_path):
    path = _write(tmp_path / "w.xml", [_parked("obstacle_000", 5, 1, **BOX), _parked("obstacle_001", 5, -2, **CAPSULE)])
    world = read_world(path)
    assert [o.shape for o in world.obstacles] == ["box", "capsule"]
    assert world.obstacles[0].half_extents == (0.4, 0.25) and world.obstacles[1].yaw == 1.1
    model = load_model(path, beam_sensors=False)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    box, cap = model.geom("obstacle_000"), model.geom("obstacle_001")
    assert box.type == mujoco.mjtGeom.mjGEOM_BOX and np.allclose(box.size, [0.4, 0.25, 0.5])
    assert cap.type == mujoco.mjtGeom.mjGEOM_CAPSULE and np.allclose(cap.size[:2], [0.35, 0.6])
    # The box's long axis points along its yaw; the capsule lies flat along its yaw at the height of its radius.
    assert np.allclose(data.geom_xmat[box.id].reshape(3, 3)[:2, 0], [math.cos(0.3), math.sin(0.3)])
    axis = data.geom_xmat[cap.id].reshape(3, 3)[:, 2]
    assert np.allclose(np.abs(axis), [abs(math.cos(1.1)), abs(math.sin(1.1)), 0], atol=1e-9)
    assert data.geom_xpos[cap.id][2] == pytest.approx(0.35)


@pytest.mark.parametrize(
    ("shape", "message"),
    [
        ({"shape": "box", "half_length": 0.4, "half_width": 0.2}, "radius 0"),
        ({"shape": "capsule", "radius": 0.3}, "half_length > 0"),
        ({"shape": "cylinder", "half_length": 0.3}, "no half_length"),
        ({"shape": "cone"}, "unknown shape"),
    ],
)
def test_malformed_shapes_are_refused(shape, message):
    o = obstacle("obstacle_000", [[0, 0, 0], [1, 1, 1]])
    with pytest.raises(WorldError, match=message):
        Obstacle(o.name, o.trajectory, **shape)


def _ray_box(origin, dirs, centre, yaw, hx, hy):
    """Distances along unit rays (k, 2) to a rotated rectangle (slab method); inf if missed."""
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, s], [-s, c]])
    o = rot @ (np.asarray(origin) - centre)
    d = dirs @ rot.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (np.array([-hx, -hy]) - o) / d
        t2 = (np.array([hx, hy]) - o) / d
    near = np.nanmax(np.minimum(t1, t2), axis=1)
    far = np.nanmin(np.maximum(t1, t2), axis=1)
    return np.where((near <= far) & (far > 0), np.maximum(near, 0), np.inf)


def _ray_circle(origin, dirs, centre, r):
    o = np.asarray(origin) - centre
    b = dirs @ o
    disc = b * b - (o @ o - r * r)
    t = -b - np.sqrt(np.where(disc >= 0, disc, np.nan))
    return np.where((disc >= 0) & (t > 0), t, np.inf)


def _ray_stadium(origin, dirs, centre, yaw, half_length, r):
    axis = np.array([math.cos(yaw), math.sin(yaw)])
    ends = [centre + half_length * axis, centre - half_length * axis]
    return np.minimum.reduce(
        [_ray_box(origin, dirs, centre, yaw, half_length, r), *(_ray_circle(origin, dirs, e, r) for e in ends)]
    )


def test_the_scan_sees_boxes_and_capsules_where_they_are(tmp_path):
    # The robot at the barn spawn (11, 0) facing -x; a box ahead-left, a capsule ahead-right.
    box_c, cap_c = np.array([8.5, 1.2]), np.array([8.0, -1.5])
    path = _write(
        tmp_path / "w.xml", [_parked("obstacle_000", *box_c, **BOX), _parked("obstacle_001", *cap_c, **CAPSULE)]
    )
    sim = Simulation(path)
    episode = Episode(sim, get_protocol("barn"), seed=0)
    episode.observe()
    laser = sim.data.site_xpos[sim.laser.site].copy()
    ranges = sim.laser.cast(sim.model, sim.data, math.pi)
    angles = sim.laser.angles + math.pi
    dirs = np.column_stack([np.cos(angles), np.sin(angles)])
    # At the laser's height (0.30 m) a capsule lying on the floor is a stadium of the chord's half width.
    chord = math.sqrt(CAPSULE["radius"] ** 2 - (JACKAL.laser_z - CAPSULE["radius"]) ** 2)
    expected = np.minimum(
        _ray_box(laser[:2], dirs, box_c, BOX["yaw"], BOX["half_length"], BOX["half_width"]),
        _ray_stadium(laser[:2], dirs, cap_c, CAPSULE["yaw"], CAPSULE["half_length"], chord),
    )
    hit = np.isfinite(expected)
    assert hit.sum() > 60, "both shapes cover many beams"
    assert np.allclose(ranges[hit], expected[hit], atol=1e-6)
    # Beams that miss both shapes reach the walls, further away than either.
    assert np.all(ranges[~hit] > 2.0)


def _drive_into(tmp_path, shape_kwargs, x_face: float, name: str):
    """Drive `straight` from the barn spawn towards -x into a parked obstacle whose near face is at x_face."""
    return run_episode(
        _write(tmp_path / f"{name}.xml", [_parked("obstacle_000", *shape_kwargs.pop("at"), **shape_kwargs)], name=name),
        get_planner("straight"),
        get_protocol("barn"),
        seed=0,
    )


def test_boxes_and_capsules_stop_the_robot_where_their_faces_are(tmp_path):
    # Three obstacles with their near face at x = 7 across the robot's straight line y = 0.
    cyl = _drive_into(tmp_path, {"at": (6.5, 0.0), "radius": 0.5}, 7.0, "cyl")
    box = _drive_into(tmp_path, {"at": (6.6, 0.0), **BOX, "yaw": 0.0}, 7.0, "box")
    cap = _drive_into(tmp_path, {"at": (6.65, 0.0), **CAPSULE, "yaw": math.pi / 2}, 7.0, "cap")
    for r in (cyl, box, cap):
        assert r.outcome is Outcome.COLLISION and r.reason == "hit obstacle_000"
    # A flat face and a round one at the same x are reached at the same moment, to a few physics steps.
    assert box.sim_time == pytest.approx(cyl.sim_time, abs=0.03)
    assert cap.sim_time == pytest.approx(cyl.sim_time, abs=0.03)


def test_clearance_to_a_box_passed_at_a_known_distance(tmp_path):
    # The robot drives straight along y = 0 past a box whose near side is at y = 0.7.
    path = _write(tmp_path / "w.xml", [_parked("obstacle_000", 5.0, 0.95, **{**BOX, "yaw": 0.0})])
    recording = tmp_path / "run.mcap"
    result = run_episode(
        path, get_planner("straight"), get_protocol("barn"), seed=0, observers=[McapRecorder(recording)]
    )
    assert result.outcome is Outcome.SUCCESS
    assert result.min_clearance == pytest.approx(0.7 - JACKAL.width / 2, abs=0.01)
    # The recording puts the box among its cubes; reading it back restores the position.
    rec = read_recording(recording)
    _, xy = obstacle_track(rec, read_world(path))
    assert np.allclose(xy[:, 0], [5.0, 0.95])
    assert len(rec.topic("/world/obstacles")[0][1].entities[0].cubes) == 1


def test_shape_clearance_matches_mujoco_distances():
    """The vectorised footprint distance against MuJoCo's own geom distance, for random poses."""
    spec = mujoco.MjSpec()
    robot = spec.worldbody.add_body(name="robot", mocap=True)
    robot.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[HALF[0], HALF[1], 1.0], pos=[0, 0, 1.0])
    box = spec.worldbody.add_body(name="box", mocap=True)
    box.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.4, 0.25, 0.5], pos=[0, 0, 0.5])
    cap = spec.worldbody.add_body(name="cap", mocap=True)
    cap.add_geom(
        type=mujoco.mjtGeom.mjGEOM_CAPSULE,
        size=[0.35, 0.6, 0],
        pos=[0, 0, 0.35],
        quat=[math.sqrt(0.5), 0, math.sqrt(0.5), 0],
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    n = 200
    poses = np.column_stack([rng.uniform(-2, 2, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    centres = rng.uniform(-2, 2, (n, 2, 2))
    yaws = np.array([0.3, 1.1])
    ours = np.stack(
        [
            shape_clearance(poses, centres[:, k : k + 1], yaws[k : k + 1], np.array([he]), np.array([r]), HALF)
            for k, (he, r) in enumerate((((0.4, 0.25), 0.0), ((0.6, 0.0), 0.35)))
        ],
        axis=1,
    )
    fromto = np.zeros(6)
    checked = 0
    for i in range(n):
        data.mocap_pos[0, :2], data.mocap_quat[0] = (
            poses[i, :2],
            [math.cos(poses[i, 2] / 2), 0, 0, math.sin(poses[i, 2] / 2)],
        )
        for k in range(2):
            data.mocap_pos[k + 1, :2] = centres[i, k]
            data.mocap_quat[k + 1] = [math.cos(yaws[k] / 2), 0, 0, math.sin(yaws[k] / 2)]
        mujoco.mj_kinematics(model, data)
        for k in range(2):
            d = mujoco.mj_geomDistance(model, data, 0, k + 1, 10.0, fromto)
            if d > 1e-6:  # apart: the distances agree; overlapping: ours says <= 0
                assert ours[i, k] == pytest.approx(d, abs=1e-6)
                checked += 1
            else:
                assert ours[i, k] <= 1e-9
    assert checked > 200


def test_shape_clearance_equals_the_cylinder_formula_for_cylinders():
    rng = np.random.default_rng(3)
    poses = rng.uniform(-3, 3, (40, 3))
    xy = rng.uniform(-3, 3, (40, 5, 2))
    r = rng.uniform(0.1, 0.6, 5)
    general = shape_clearance(poses, xy, rng.uniform(0, 3, 5), np.zeros((5, 2)), r, HALF)
    assert np.allclose(general, footprint_clearance(poses, xy, r, HALF), atol=1e-12)


def test_shape_mix_draws_shapes_without_changing_the_motions():
    profiles = get_profile_set("table1")
    plain = generate_world(250, profiles)
    shaped = generate_world(250, profiles, shapes=SHAPE_MIXES["mixed"])
    assert shaped == generate_world(250, profiles, shapes=SHAPE_MIXES["mixed"]), "deterministic"
    assert {o.shape for o in shaped.obstacles} == {"cylinder", "box", "capsule"}
    for a, b in zip(plain.obstacles, shaped.obstacles, strict=True):
        assert np.array_equal(a.trajectory.xy, b.trajectory.xy) and np.array_equal(
            a.trajectory.times, b.trajectory.times
        )
    mix = SHAPE_MIXES["mixed"]
    for o in shaped.obstacles:
        if o.shape == "box":
            assert mix.box_half_size[0] <= min(o.half_extents) <= max(o.half_extents) <= mix.box_half_size[1]
        if o.shape == "capsule":
            assert mix.capsule_radius[0] <= o.radius <= mix.capsule_radius[1]
    assert generate_world(250, profiles, shapes=SHAPE_MIXES["cylinder"]) == plain
