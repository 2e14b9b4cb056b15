"""The vector environment equals the single one step for step; its batched laser and
schedules equal the per-world ones (learn extra)."""

import numpy as np
import pytest

from tests.conftest import require

gymnasium = require("gymnasium", "learn")

import mujoco  # noqa: E402

import dynabarn.learn  # noqa: E402  (registers DynaBARN-v0)
from dynabarn.learn.env import DynaBARNEnv  # noqa: E402
from dynabarn.learn.vector_env import DynaBARNVectorEnv  # noqa: E402
from dynabarn.mjcf import read_world  # noqa: E402
from dynabarn.sim import Simulation  # noqa: E402
from dynabarn.sim.ray_batch import BatchCaster, supports  # noqa: E402
from dynabarn.worlds.schedule import SchedulePlayer  # noqa: E402
from dynabarn.worlds.schedule_batch import ScheduleBatch  # noqa: E402
from dynabarn.worldset import resolve_world  # noqa: E402

LASER_GRID = 0.001


def _lockstep(vec: DynaBARNVectorEnv, kwargs: dict, steps: int, seed: int) -> int:
    """Step `vec` and one single environment per world with the same random actions;
    assert equality to the laser's grid; returns the number of episodes that ended."""
    n = vec.num_envs
    singles = [DynaBARNEnv(**kwargs) for _ in range(n)]
    obs_v, info_v = vec.reset(seed=seed)
    for i, env in enumerate(singles):
        obs, info = env.reset(seed=seed + i)
        np.testing.assert_array_equal(obs, obs_v[i])
        assert info["world_id"] == info_v["world_id"][i]
    rng = np.random.default_rng(seed)
    pending = np.zeros(n, dtype=bool)
    ended = 0
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        actions[:, 0] = np.abs(actions[:, 0])  # mostly forward, so episodes end and reset
        obs_v, rew_v, term_v, trunc_v, info_v = vec.step(actions)
        for i, env in enumerate(singles):
            if pending[i]:  # Gymnasium's NEXT_STEP autoreset: this step resets world i
                obs, _ = env.reset()
                rew, term, trunc = 0.0, False, False
            else:
                obs, rew, term, trunc, _ = env.step(actions[i])
            # The scan to its 1 mm grid (one grid step where a range lands within rounding
            # of a grid line), the local goal and everything else exactly.
            assert np.max(np.abs(obs[:720] - obs_v[i, :720])) <= LASER_GRID + 1e-6
            np.testing.assert_array_equal(obs[720:], obs_v[i, 720:])
            assert rew == pytest.approx(rew_v[i], abs=1e-12) and term == term_v[i] and trunc == trunc_v[i]
            pending[i] = term or trunc
        ended += int(pending.sum())
    for env in singles:
        env.close()
    return ended


def test_vector_env_equals_single_envs_in_process():
    kwargs = {"world_set": "dynabarn300"}
    vec = DynaBARNVectorEnv(5, workers=0, **kwargs)
    try:
        assert _lockstep(vec, kwargs, steps=250, seed=11) >= 5  # autoresets were exercised
    finally:
        vec.close()


@pytest.mark.slow
def test_vector_env_equals_single_envs_across_workers_and_splits():
    kwargs = {"split": "train", "split_seed": 2}
    vec = DynaBARNVectorEnv(4, workers=2, **kwargs)
    try:
        assert vec.single_observation_space.shape == (722,) and vec.observation_space.shape == (4, 722)
        assert _lockstep(vec, kwargs, steps=150, seed=3) >= 2
    finally:
        vec.close()
    assert all(not p.is_alive() for p in vec._procs) and not vec._procs


@pytest.mark.slow
def test_vector_env_returns_its_own_observations_and_a_dead_worker_is_one_clear_error():
    # The workers write into a buffer shared with this process: what step returned must not
    # change when the next step writes it again. A worker that died is named, not a pipe error.
    vec = DynaBARNVectorEnv(4, workers=2, world_set="paper60", difficulty="hard")
    try:
        first, _ = vec.reset(seed=0)
        kept = first.copy()
        second, *_ = vec.step(np.full((4, 2), 0.5, np.float32))
        np.testing.assert_array_equal(first, kept)
        assert not np.array_equal(first[2:], second[2:])  # the worker's rows did change
        vec._procs[0].kill()
        vec._procs[0].join()
        with pytest.raises(RuntimeError, match="worker process 1 ended"):
            vec.step(np.zeros((4, 2), np.float32))
    finally:
        vec.close()


def test_make_vec_uses_the_vector_entry_point():
    vec = gymnasium.make_vec(
        dynabarn.learn.ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", workers=0, world_set="paper60"
    )
    try:
        assert isinstance(vec.unwrapped, DynaBARNVectorEnv)
        obs, _ = vec.reset(seed=0)
        obs, rew, *_ = vec.step(np.zeros((2, 2), np.float32))
        assert obs.shape == (2, 722) and rew.shape == (2,)
    finally:
        vec.close()


def test_batch_caster_equals_mj_multiray():
    ids = (0, 60, 105, 137, 160, 205, 250, 299)
    sims = [Simulation(resolve_world(i)) for i in ids]
    assert all(supports(s) for s in sims)
    caster = BatchCaster(sims)
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(40):
        origins, yaws, centres, reference = [], [], [], []
        for s in sims:
            # Anywhere off the walls, also far outside the arena (where mj_multiRay leaves out far walls).
            s.reset((rng.uniform(-9, 40), rng.uniform(-9, 9), rng.uniform(-np.pi, np.pi)))
            mujoco.mj_kinematics(s.model, s.data)
            o = s.data.site_xpos[s.laser.site][:2].copy()
            xy = rng.uniform(-10, 10, (len(s.radii), 2))
            clear = np.hypot(*(xy - o).T) > s.radii + 0.05
            xy[~clear] += 5.0  # never around the laser itself
            s.set_obstacles(xy)
            mujoco.mj_kinematics(s.model, s.data)
            yaw = float(s.data.qpos[2])
            reference.append(s.laser.cast(s.model, s.data, yaw))
            origins.append(s.data.site_xpos[s.laser.site].copy())
            yaws.append(yaw)
            centres.append(xy)
        got = caster.cast(np.array(origins), np.array(yaws), np.concatenate(centres))
        ref = np.array(reference)
        worst = max(worst, float(np.max(np.abs(got - ref))))
    assert worst < 1e-9


def test_batch_caster_leaves_shapes_and_static_fields_to_mj_multiray(tmp_path):
    from dynabarn.mjcf import write_world
    from dynabarn.worlds.generate import generate_world
    from dynabarn.worlds.profiles import get_profile_set, get_shape_mix, get_static_field

    table1 = get_profile_set("table1")
    shaped = generate_world(205, table1, shapes=get_shape_mix("mixed"))
    field = generate_world(205, table1, static_field=get_static_field("barn-grid"))
    for name, world in (("shaped", shaped), ("field", field)):
        write_world(world, tmp_path / f"{name}.xml")
        assert not supports(Simulation(tmp_path / f"{name}.xml"))
    assert supports(Simulation(resolve_world(205)))


def test_schedule_batch_has_each_worlds_bits():
    rng = np.random.default_rng(1)
    worlds = [read_world(resolve_world(i)) for i in (0, 105, 137, 250, 299)]
    players = [SchedulePlayer(w, clock_offset=float(rng.uniform(0, 5))) for w in worlds]
    batch = ScheduleBatch(players)
    offsets = np.arange(20) * 0.005
    for _ in range(300):
        t = np.round(rng.uniform(0, 300, len(players)) / 0.005) * 0.005
        pos, vel = batch.positions_at(t[None, :] + offsets[:, None])
        for i, p in enumerate(players):
            ref_pos, ref_vel = p.positions_at(t[i] + offsets)
            np.testing.assert_array_equal(pos[i], ref_pos)
            np.testing.assert_array_equal(vel[i], ref_vel)


@pytest.mark.parametrize("span", [0.1, 40.0])
def test_schedule_batch_counts_keys_exactly_when_a_period_passes_many(span):
    # A 0.1 s period compares only the next few keys; one spanning 40 s passes many and
    # must fall back to comparing all of them: the same bits either way.
    rng = np.random.default_rng(2)
    worlds = [read_world(resolve_world(i)) for i in (3, 150, 299)]
    players = [SchedulePlayer(w, clock_offset=float(rng.uniform(0, 5))) for w in worlds]
    batch = ScheduleBatch(players)
    offsets = np.linspace(0.0, span, 20)
    for _ in range(200):
        t = rng.uniform(0, 300, len(players))
        pos, vel = batch.positions_at(t[None, :] + offsets[:, None])
        for i, p in enumerate(players):
            ref_pos, ref_vel = p.positions_at(t[i] + offsets)
            np.testing.assert_array_equal(pos[i], ref_pos)
            np.testing.assert_array_equal(vel[i], ref_vel)


def test_local_goal_batch_has_each_planners_bits():
    # Every world's plan walked in one numpy pass must give what each planner's own walk
    # gives: anywhere in and around the arena (unreachable cells, the goal's cell, the
    # grid's edge), on the plan, at several lookaheads, and after plans were dropped for
    # others (a capacity smaller than the plans met; the shipped worlds share one plan, so
    # other goals make the others).
    from dynabarn.learn.shared_worlds import shared_world
    from dynabarn.planners.global_planner import GlobalPlanner, local_goals_in_robot
    from dynabarn.planners.local_goal_batch import LocalGoalBatch

    shipped = shared_world(str(resolve_world(137)))[1]
    walls = np.array([[-10, 0, 0.5, 20], [0, 10, 20, 0.5], [0, -10, 20, 0.5]], dtype=float)
    others = [GlobalPlanner(walls, np.array(goal)) for goal in ((-9.0, 5.0), (-9.0, -5.0), (0.0, 0.0), (5.0, 8.0))]
    planners = [shipped, *others]
    batch = LocalGoalBatch(capacity=4)
    rng = np.random.default_rng(3)
    for _ in range(200):
        chosen = [planners[k] for k in rng.choice(len(planners), size=int(rng.integers(1, 5)), replace=False)]
        poses = np.column_stack(
            [rng.uniform(-13, 16, len(chosen)), rng.uniform(-13, 16, len(chosen)), rng.uniform(-4, 4, len(chosen))]
        )
        lookahead = float(rng.choice([0.1, 0.75, 2.0, 3.3]))
        np.testing.assert_array_equal(
            batch.local_goals_in_robot(chosen, poses, lookahead), local_goals_in_robot(chosen, poses, lookahead)
        )
    for planner in planners:
        plan = planner.plan(11.0, 0.0)
        poses = np.column_stack([plan, np.linspace(-3, 3, len(plan))])
        many = [planner] * len(plan)
        np.testing.assert_array_equal(
            batch.local_goals_in_robot(many, poses, 2.0), local_goals_in_robot(many, poses, 2.0)
        )
    assert len(batch._slots) == 4  # plans were dropped and copied in again
    with pytest.raises(ValueError, match="capacity"):
        batch.local_goals_in_robot(planners, np.zeros((len(planners), 3)), 2.0)
