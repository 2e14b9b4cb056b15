"""Mixed worlds: a BARN-style field of static cylinders with DynaBARN's moving obstacles."""

from dataclasses import replace

import numpy as np
import pytest

from dynabarn.cli import worlds_main
from dynabarn.errors import ProfileError
from dynabarn.metrics import Outcome
from dynabarn.mjcf import load_model, read_world, write_world
from dynabarn.planners import get_planner
from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.protocol import get_protocol
from dynabarn.sim import Simulation, run_episode
from dynabarn.worlds.generate import generate_world
from dynabarn.worlds.profiles import STATIC_FIELDS, StaticField, get_profile_set
from dynabarn.worlds.static_field import _enclosed, _smooth, blocked_for_robot, crosses, generate_static_field
from dynabarn.worldset import read_index
from tests.test_barn import NARROW_DWA

FIELD = STATIC_FIELDS["barn-grid"]


def test_cellular_automaton_rules():
    # A lone cell dies (0 neighbours); a cell with 5 filled neighbours fills; a full block's inside is enclosed.
    grid = np.zeros((5, 5), dtype=bool)
    grid[2, 2] = True
    assert not _smooth(grid, 1).any()
    grid = np.zeros((5, 5), dtype=bool)
    grid[1, 1:4] = grid[2, 1] = grid[2, 3] = True  # 5 neighbours around the empty (2, 2)
    assert _smooth(grid, 1)[2, 2]
    block = np.zeros((5, 5), dtype=bool)
    block[1:4, 1:4] = True
    assert np.flatnonzero(_enclosed(block).ravel()).tolist() == [12]


def test_crossing_check():
    free = np.zeros((10, 10), dtype=bool)
    assert crosses(free)
    wall = free.copy()
    wall[5, :] = True
    assert not crosses(wall)
    wall[5, 7] = False  # one free cell in the wall is a passage
    assert crosses(wall)
    # The robot (half width 0.215 m) does not fit between cylinders two cells (0.30 m) apart.
    filled = np.zeros((9, 9), dtype=bool)
    filled[4, ::2] = True
    assert not crosses(blocked_for_robot(filled, 0.15, 0.075))


def test_fields_are_deterministic_crossable_and_on_the_lattice():
    a = generate_static_field(np.random.default_rng(5), FIELD)
    assert a == generate_static_field(np.random.default_rng(5), FIELD)
    xy = np.array(a)[:, :2]
    assert 200 < len(a) < 1500
    assert xy[:, 0].min() > FIELD.x_range[0] and xy[:, 0].max() < FIELD.x_range[1]
    assert xy[:, 1].min() > FIELD.y_range[0] and xy[:, 1].max() < FIELD.y_range[1]
    cells = (xy - [FIELD.x_range[0], FIELD.y_range[0]]) / FIELD.cell - 0.5
    assert np.allclose(cells, np.round(cells), atol=1e-6)


def test_mixed_world_keeps_the_motions_and_the_global_planner_crosses_the_field(tmp_path):
    profiles = get_profile_set("table1")
    plain = generate_world(137, profiles)
    mixed = generate_world(137, profiles, static_field=FIELD)
    assert mixed.obstacles == plain.obstacles
    assert len(mixed.layout.cylinders) > 200 and mixed.provenance["static_field"]["name"] == "barn-grid"
    path = tmp_path / "world_137.xml"
    write_world(mixed, path)
    assert read_world(path) == mixed
    model = load_model(path, beam_sensors=False)
    assert sum(model.geom(i).name.startswith("static_") for i in range(model.ngeom)) == len(mixed.layout.cylinders)
    # The static map the planners get holds the field, and a path through it exists.
    sim = Simulation(path)
    info = sim.episode_info(get_protocol("barn"), seed=0)
    assert len(info.static_obstacles) == len(mixed.layout.cylinders)
    planner = GlobalPlanner.for_robot(info.walls, info.goal, info.footprint, info.static_obstacles)
    assert np.isfinite(planner.cost_to_go(11.0, 0.0))
    plan = planner.plan(11.0, 0.0)
    assert len(plan) > 10
    static = np.asarray(mixed.layout.cylinders)
    gaps = np.hypot(plan[:, None, 0] - static[None, :, 0], plan[:, None, 1] - static[None, :, 1]) - static[None, :, 2]
    assert gaps.min() > 0.15, "the plan keeps clear of every cylinder"


def test_dwa_crosses_the_static_field(tmp_path):
    # The field alone (the movers would make the outcome a matter of timing): DWA, with the
    # narrow collision check of BARN's passages, threads it. Over seeds (laser noise), with a
    # margin: it crosses world 137's field in all 4 trials here. (World 60's field holds a
    # pocket near x = 0 where DWA, a local planner, stalls in 4 of 5 trials.)
    mixed = generate_world(137, get_profile_set("table1"), static_field=FIELD)
    path = tmp_path / "field.xml"
    write_world(replace(mixed, obstacles=()), path)
    results = [
        run_episode(path, get_planner("dwa", **NARROW_DWA), get_protocol("barn"), seed=seed) for seed in range(4)
    ]
    crossed = [r for r in results if r.outcome is Outcome.SUCCESS]
    assert len(crossed) >= 3, [r.outcome for r in results]
    assert all(0 < r.min_clearance < 0.5 for r in crossed), "it passed close to the field's cylinders"


@pytest.mark.slow
def test_cli_generates_mixed_worlds_with_shapes(tmp_path, capsys):
    out = tmp_path / "mixed"
    assert worlds_main(["generate", "--shapes", "mixed", "--static", "barn-grid", "--out", str(out)]) == 0
    index = read_index(out)
    assert len(index["worlds"]) == 300 and index["static_field"]["name"] == "barn-grid"
    assert index["shapes"]["name"] == "mixed"
    entry = index["worlds"][137]
    assert entry["n_static"] > 200 and set(entry["shapes"]) <= {"cylinder", "box", "capsule"}
    world = read_world(out / entry["file"])
    assert world.obstacles[0].trajectory == generate_world(137, get_profile_set("table1")).obstacles[0].trajectory


def test_bad_static_fields_are_refused():
    with pytest.raises(ProfileError, match="below -10"):
        StaticField("x", y_range=(-12.0, 12.0))
    with pytest.raises(ProfileError, match="fill must be below 1"):
        StaticField("x", fill=(0.5, 1.0))
    with pytest.raises(SystemExit):
        worlds_main(["generate", "--static", "forest"])


def test_closed_form_scan_of_static_cylinders_equals_mujoco_ray_casting(tmp_path):
    import math

    import mujoco

    from dynabarn.robot import LASER_GEOM_GROUPS
    from dynabarn.worlds.profiles import SHAPE_MIXES

    world = generate_world(250, get_profile_set("table1"), static_field=FIELD, shapes=SHAPE_MIXES["mixed"])
    path = tmp_path / "w.xml"
    write_world(world, path)
    sim = Simulation(path)
    laser = sim.laser
    assert len(laser.static) == len(world.layout.cylinders)
    rng = np.random.default_rng(0)
    poses = [
        (11.0, 0.0, math.pi),
        *zip(rng.uniform(-3, 3, 12), rng.uniform(-8, 8, 12), rng.uniform(-3, 3, 12), strict=True),
    ]
    geomid, dist = np.zeros(laser.n, dtype=np.int32), np.zeros(laser.n)
    hits_static = 0
    for pose in poses:
        sim.reset(pose)
        sim.set_obstacles(rng.uniform(-5, 5, (len(world.obstacles), 2)))
        mujoco.mj_kinematics(sim.model, sim.data)
        ours = laser.cast(sim.model, sim.data, pose[2])
        # MuJoCo over every geom the laser sees, static cylinders included.
        mujoco.mj_multiRay(
            sim.model, sim.data, sim.data.site_xpos[laser.site], laser._vec, LASER_GEOM_GROUPS, 1,
            laser.robot_body, geomid, dist, None, laser.n, 30.0,
        )  # fmt: skip
        reference = np.where(geomid < 0, 30.0, dist)
        static = np.asarray(world.layout.cylinders)
        origin = sim.data.site_xpos[laser.site][:2]
        if np.all(np.hypot(*(static[:, :2] - origin).T) > static[:, 2] + 1e-3):  # the laser not inside one
            assert np.allclose(ours, reference, atol=1e-9)
            hits_static += sum(sim.model.geom(g).name.startswith("static_") for g in geomid if g >= 0)
            # The geoms the beams ended on agree too: a moving obstacle behind a static
            # cylinder is hidden (the tracking scores' "in view" counts beams per obstacle).
            ours_obstacle = sim.obstacle_of_geom[np.maximum(laser.geom_ids, 0)]
            ours_obstacle[laser.geom_ids < 0] = -1
            mujoco_obstacle = sim.obstacle_of_geom[np.maximum(geomid, 0)]
            mujoco_obstacle[geomid < 0] = -1
            assert np.array_equal(ours_obstacle, mujoco_obstacle)
    assert hits_static > 1000


@pytest.mark.parametrize("world_id", [0, 250])
def test_oracle_threads_the_static_field(tmp_path, world_id):
    # The oracle checks its rollouts against the static cylinders (a distance transform of the known map).
    mixed = generate_world(world_id, get_profile_set("table1"), static_field=FIELD)
    path = tmp_path / "field.xml"
    write_world(replace(mixed, obstacles=()), path)
    result = run_episode(path, get_planner("oracle"), get_protocol("barn"), seed=0)
    assert result.outcome is Outcome.SUCCESS, result.reason
    assert result.min_clearance > 0.0
