"""The Warp backend's worlds (`learn.warp_worlds`) against MuJoCo's C engine, on Warp's CPU
device: the same commands give the same robot, obstacles, scans and contacts, within
float32's reach (not bit for bit: another solver path). Warp compiles its kernels on first
use (about 40 s on an idle 2-core machine) and keeps them in its kernel cache."""

from __future__ import annotations

import numpy as np
import pytest

from dynabarn.protocol import get_protocol
from dynabarn.sim.episode import Episode
from dynabarn.sim.simulation import Simulation
from dynabarn.worldset import resolve_world

pytest.importorskip("warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
pytest.importorskip("mujoco_warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")

from dynabarn.learn.warp_worlds import COLLISION, RUNNING, SUCCESS, TIMEOUT, WarpWorlds

WORLD = str(resolve_world("137"))  # from any current folder
POSE_M = 1e-3
"""[m, rad] the largest pose difference allowed (measured: 0.044 mm over a 112-period episode)."""
SCAN_M = 1.5e-3
"""[m] a beam may differ by one step of the laser's 1 mm grid (float32 rounding near a half)."""
OBSTACLE_M = 1e-4
"""[m] scheduled obstacles (measured: about 1 um in float32)."""


def _c_episode(seed: int = 0) -> tuple[Simulation, Episode]:
    sim = Simulation(WORLD)
    return sim, Episode(sim, get_protocol("barn"), seed=seed)


def _batch(episode: Episode, sim: Simulation, n: int = 2, **options) -> WarpWorlds:
    """n Warp worlds where the C engine's episode starts (its spawn and obstacles' clock)."""
    batch = WarpWorlds(WORLD, n, device="cpu", laser_noise=False, **options)
    batch.reset(np.ones(n, bool), np.tile(sim.data.qpos[:3], (n, 1)), np.full(n, episode.clock_offset), np.arange(n))
    return batch


def _c_ranges(sim: Simulation) -> np.ndarray:
    ranges = sim.laser.cast(sim.model, sim.data, float(sim.data.qpos[2]))
    return np.clip(np.rint(ranges / 1e-3) * 1e-3, 0.1, 30.0)


def test_the_batch_follows_the_c_engine_through_a_planners_episode():
    """`predictive` drives world 137 on the C engine to the goal; the same commands in two
    Warp worlds give the same poses, obstacles and scans every period, and no contact."""
    from dynabarn.planners.registry import get_planner

    sim, episode = _c_episode()
    batch = _batch(episode, sim)
    planner = get_planner("predictive")
    planner.reset(episode.info)
    periods = 0
    while episode.outcome is None:
        v, w = planner.act(episode.observe())
        assert np.abs(batch.pose.numpy()[:, :3] - sim.data.qpos[:3]).max() <= POSE_M, periods
        mocap = batch.d.mocap_pos.numpy()[:, : batch.n_obstacles, :2]
        assert np.abs(mocap - sim.data.mocap_pos[: batch.n_obstacles, :2]).max() <= OBSTACLE_M, periods
        assert np.abs(batch.scan.numpy() - _c_ranges(sim)).max() <= SCAN_M, periods
        episode.apply(v, w)
        batch.step(np.tile([v, w], (2, 1)))
        periods += 1
        if episode.outcome is None:
            assert list(batch.outcome.numpy()) == [RUNNING] * 2, periods
    assert episode.outcome.value == "success" and periods > 100
    assert not batch.touched.numpy().any()
    # Judged on the device: the goal reached at the C engine's step (float32 may move a
    # boundary crossing by one 5 ms step).
    assert list(batch.outcome.numpy()) == [SUCCESS] * 2
    assert np.abs(batch.end_step.numpy() - episode.step).max() <= 1, (batch.end_step.numpy(), episode.step)


def test_a_contact_is_seen_in_the_period_the_c_engine_ends_with_it():
    """Full speed on a weaving line into world 137's obstacles: the C engine ends the
    episode with a collision, and the Warp worlds touch in that same period, at its step."""
    sim, episode = _c_episode()
    batch = _batch(episode, sim)
    for period in range(100):
        episode.observe()
        command = (1.0, 0.3 * np.sin(period / 8.0))
        episode.apply(*command)
        batch.step(np.tile(command, (2, 1)))
        touched = batch.touched.numpy()
        if episode.outcome is not None:
            assert episode.outcome.value == "collision" and touched.all(), (period, touched)
            assert list(batch.outcome.numpy()) == [COLLISION] * 2
            assert list(batch.end_step.numpy()) == [episode.step] * 2
            return
        assert not touched.any(), period
    pytest.fail("the C engine's episode did not collide")


def test_a_robot_that_never_leaves_its_spawn_times_out_as_on_the_c_engine():
    """The clock runs from 0 when the robot never starts it: with a 1 s limit, standing
    still ends both at the same step as a timeout."""
    import dataclasses

    sim, episode = _c_episode()
    episode.protocol = protocol = dataclasses.replace(episode.protocol, time_limit=1.0)
    batch = _batch(episode, sim, protocol=protocol)
    while episode.outcome is None:
        episode.observe()
        episode.apply(0.0, 0.0)
        batch.step(np.zeros((2, 2)))
    assert episode.outcome.value == "timeout"
    assert list(batch.outcome.numpy()) == [TIMEOUT] * 2 and list(batch.end_step.numpy()) == [episode.step] * 2


def test_the_laser_noise_is_each_worlds_own_and_the_same_for_the_same_seed():
    """1 mm of Gaussian noise before the grid (the BARN Jackal's), drawn from each world's
    seed and period: equal seeds give equal scans, others differ; its spread is the laser's."""
    sim, episode = _c_episode()
    clean = _batch(episode, sim, n=3)
    noisy = WarpWorlds(WORLD, 3, device="cpu")
    noisy.reset(np.ones(3, bool), np.tile(sim.data.qpos[:3], (3, 1)), np.full(3, episode.clock_offset), [7, 7, 8])
    scans, truth = noisy.scan.numpy().copy(), clean.scan.numpy()  # numpy(): a view on the CPU device
    assert np.array_equal(scans[0], scans[1]) and not np.array_equal(scans[0], scans[2])
    inside = truth[0] < 29.0  # beams clipped at the range's end keep no noise above it
    error = (scans[:, inside] - truth[:, inside]).ravel()
    assert 0.8e-3 < error.std() < 1.3e-3 and abs(error.mean()) < 2e-4, (error.std(), error.mean())
    noisy.step(np.zeros((3, 2)))
    assert not np.array_equal(noisy.scan.numpy()[0], scans[0])  # each period draws anew


def test_a_reset_mask_restarts_its_worlds_and_leaves_the_others_going():
    sim, episode = _c_episode()
    spawn = np.tile(sim.data.qpos[:3], (2, 1))
    batch = _batch(episode, sim)
    for _ in range(5):
        batch.step(np.tile([0.8, 0.0], (2, 1)))
    before = batch.pose.numpy()[:, :3].copy()
    assert np.all(np.hypot(*(before[:, :2] - spawn[:, :2]).T) > 0.3)  # both drove on
    batch.reset(np.array([False, True]), spawn, np.full(2, episode.clock_offset + 1.0), [0, 1])
    after = batch.pose.numpy()[:, :3]
    assert np.array_equal(after[0], before[0]) and np.allclose(after[1], spawn[1], atol=1e-6)
    assert list(batch.steps.numpy()) == [5 * batch.k, 0]
    assert batch.clock_offset.numpy()[0] == pytest.approx(episode.clock_offset)
    batch.step(np.tile([0.8, 0.0], (2, 1)))  # world 1 starts from rest: the acceleration limit again
    moved = np.hypot(*(batch.pose.numpy()[:, :2] - np.stack([before[0, :2], spawn[1, :2]])).T)
    assert moved[0] > moved[1] > 0.0
