"""`WarpVectorEnv` (the Warp backend's DynaBARN-v0) against `DynaBARNEnv` on the C engine,
on Warp's CPU device: the same trial and actions give the same observations, rewards and
ends, within float32's reach; worlds that end restart in the same step, keeping their
final observation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dynabarn.learn.env import DynaBARNEnv
from dynabarn.worldset import resolve_world

pytest.importorskip("warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
pytest.importorskip("mujoco_warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
torch = pytest.importorskip("torch")

from dynabarn.learn.warp_env import WarpVectorEnv  # noqa: E402

WORLD = str(resolve_world("137"))  # from any current folder
GOAL_M = 5e-3
"""[m] local goals (the pose agrees to 0.05 mm; the plan's cells are the same)."""
SCAN_M = 6e-3
"""[m] a beam: the C engine's scan carries the laser's 1 mm noise (5 sigma), the batch's none."""
GRAZING = 4
"""Beams of a scan allowed past SCAN_M: a ray that grazes an edge hits it in one engine and
passes in the other (float32 directions; seen: 11 of the 109,440 beams of a 152-period episode)."""


def _beams_off(scan: np.ndarray, expected: np.ndarray) -> int:
    return int((np.abs(scan - expected) > SCAN_M).sum())


def _steer(obs: np.ndarray) -> np.ndarray:
    """A simple pursuit of the local goal, in the environment's action units."""
    gx, gy = float(obs[720]), float(obs[721])
    return np.array([0.2, float(np.clip(math.atan2(gy, gx), -1.0, 1.0))], dtype=np.float32)


def test_an_episode_is_the_c_environments_and_the_world_restarts_in_the_same_step():
    batch = WarpVectorEnv(WORLD, 2, device="cpu", laser_noise=False, seed=3)
    obs = batch.reset()[0].numpy().copy()
    trial = int(batch.trials[0, 0])
    single = DynaBARNEnv(worlds=[137])
    expected, _ = single.reset(seed=0, options={"trial_seed": trial})
    assert np.abs(obs[0, 720:] - expected[720:]).max() <= GOAL_M
    assert _beams_off(obs[0, :720], expected[:720]) <= GRAZING
    first = obs[0].copy()
    grazed = 0
    for period in range(1000):
        action = _steer(expected)
        actions = torch.tensor(np.stack([action, _steer(obs[1])]))
        obs_t, reward, terminated, truncated, info = batch.step(actions)
        expected, c_reward, c_terminated, c_truncated, c_info = single.step(action)
        obs = obs_t.numpy().copy()
        assert reward[0].item() == pytest.approx(c_reward, abs=1e-3), period
        assert (bool(terminated[0]), bool(truncated[0])) == (c_terminated, c_truncated), period
        if c_terminated or c_truncated:
            final = info["final_observation"].numpy()[0]
            assert np.abs(final[720:] - expected[720:]).max() <= GOAL_M
            assert _beams_off(final[:720], expected[:720]) <= GRAZING
            # Restarted at once on its next trial: the spawn's first observation.
            assert np.abs(obs[0, 720:] - first[720:]).max() <= GOAL_M
            assert int(batch._episodes.numpy()[0]) == 1
            assert c_info["outcome"] in ("success", "collision", "timeout")
            break
        assert np.abs(obs[0, 720:] - expected[720:]).max() <= GOAL_M, period
        off = _beams_off(obs[0, :720], expected[:720])
        assert off <= GRAZING, (period, off)
        grazed += off
    else:
        pytest.fail("the episode did not end")
    print(f"{period + 1} periods, {grazed} beams past {SCAN_M * 1e3:g} mm")
    assert grazed <= 0.001 * 720 * period
    single.close()
