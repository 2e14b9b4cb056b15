"""A control period in one call into MuJoCo (`sim.physics_period`) equals MuJoCo's
step-by-step loop, bit for bit, through whole episodes and at the contact that ends one;
a forked simulation runs the same episode as a freshly compiled one."""

import mujoco
import numpy as np

from dynabarn.metrics import Outcome
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.sim import Simulation, run_episode
from dynabarn.sim.episode import Episode
from dynabarn.sim.physics_period import PhysicsPeriod
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worldset import resolve_world

BARN = get_protocol("barn")


def _loop(model, data, xy: np.ndarray, poses: np.ndarray) -> tuple[int, bool]:
    """The reference: obstacles placed before each mj_step, stop at the first contact."""
    for j in range(len(xy)):
        data.mocap_pos[: xy.shape[1], :2] = xy[j]
        mujoco.mj_step(model, data)
        poses[j] = data.qpos[:3]
        if data.ncon:
            return j + 1, True
    return len(xy), False


def test_a_period_in_one_call_is_the_step_by_step_loop_to_the_bit_and_stops_at_the_contact():
    world = resolve_world(250)  # hard: the robot driven straight meets an obstacle
    a, b = Simulation(world), Simulation(world)
    k = a.config.steps_per_tick
    player = SchedulePlayer(a.world, clock_offset=1.25)
    rng = np.random.default_rng(3)
    for sim in (a, b):
        sim.reset(BARN.spawn)
    periods, contact_seen = 0, False
    for period in range(600):
        xy, _ = player.positions_at(period * k * a.config.dt + np.arange(k) * a.config.dt)
        command = [rng.uniform(0.5, 2.0), 0.0, rng.uniform(-0.5, 0.5)]
        a.data.ctrl[:] = b.data.ctrl[:] = command
        pa, pb = np.full((k, 3), np.nan), np.full((k, 3), np.nan)
        ma, ca = a.physics.run(xy, pa)
        mb, cb = _loop(b.model, b.data, xy, pb)
        assert (ma, ca) == (mb, cb)
        np.testing.assert_array_equal(pa, pb)  # the unrun rows too (NaN where a contact cut the period)
        for field in ("qpos", "qvel", "qacc_warmstart", "mocap_pos", "time"):
            np.testing.assert_array_equal(getattr(a.data, field), getattr(b.data, field), err_msg=field)
        assert a.data.ncon == b.data.ncon
        periods += 1
        if ca:
            contact_seen = True
            break
    assert contact_seen and periods > 5  # the episode ran a while, then touched


def test_a_physics_period_keeps_its_buffers():
    sim = Simulation(resolve_world(0))
    physics: PhysicsPeriod = sim.physics
    buffers = [physics._state0, physics._controls, physics._states, physics._sensors]
    sim.reset(BARN.spawn)
    xy = np.zeros((physics.k, len(sim.radii), 2)) + 50.0  # obstacles far away
    poses = np.empty((physics.k, 3))
    for _ in range(3):
        assert physics.run(xy, poses) == (physics.k, False)
    assert [physics._state0, physics._controls, physics._states, physics._sensors] == buffers


def test_a_forked_simulation_runs_the_same_episode_as_a_new_one():
    world = resolve_world(137)
    template = Simulation(world)
    fork = template.fork()
    assert fork.model is template.model and fork.data is not template.data
    assert fork.physics.data is fork.data and fork.laser is not template.laser
    fresh = run_episode(world, get_planner("dwa"), BARN, seed=4)
    ep = Episode(fork, BARN, seed=4)
    planner = get_planner("dwa")
    planner.reset(ep.info)
    outcome = None
    while outcome is None:
        v, w = planner.act(ep.observe())
        outcome = ep.apply(v, w)
    assert outcome is fresh.outcome and outcome in (Outcome.SUCCESS, Outcome.COLLISION, Outcome.TIMEOUT)
    assert ep.step * ep.dt == fresh.sim_time


def test_a_world_is_parsed_and_checked_once_per_load(monkeypatch, tmp_path):
    import shutil

    from dynabarn import mjcf

    world = tmp_path / "w.xml"
    shutil.copy(resolve_world(137), world)
    world.write_bytes(world.read_bytes() + b"\n")  # bytes no other test compiled: a first load
    calls = {"parse": 0, "check": 0}
    parse, check = mjcf.parse_xml, mjcf.check_self_contained

    def counted(name, f):
        def wrapper(*a, **k):
            calls[name] += 1
            return f(*a, **k)

        return wrapper

    monkeypatch.setattr(mjcf, "parse_xml", counted("parse", parse))
    monkeypatch.setattr(mjcf, "check_self_contained", counted("check", check))
    sim = Simulation(world)
    assert calls == {"parse": 1, "check": 1} and sim.model.nmocap == len(sim.world.obstacles)
