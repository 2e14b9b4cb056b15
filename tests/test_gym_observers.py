"""A Gymnasium episode has observers as a command's has (`DynaBARN-v0`'s `observers=`): it
is recorded to MCAP through the same loop step and reads back with the result the
environment reported; a reset before the end closes the recording whole, saying why."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import require


@pytest.fixture
def env_class():
    require("gymnasium", "learn")
    from dynabarn.learn.env import DynaBARNEnv

    return DynaBARNEnv


def test_a_gym_episode_is_recorded_and_reads_back(env_class, tmp_path):
    from dynabarn.learn.observed import DRIVER, LEFT
    from dynabarn.recording import McapRecorder, read_recording

    def record(info: dict) -> list:
        return [McapRecorder(tmp_path / f"{info['world']}_{info['trial_seed']}.mcap")]

    env = env_class(worlds=[5], observers=record)
    env.reset(seed=0, options={"trial_seed": 3})
    steps = 0
    while True:
        _, _, terminated, truncated, info = env.step(np.array([0.2, 0.0], dtype=np.float32))
        steps += 1
        if terminated or truncated:
            break
    recording = read_recording(tmp_path / "world_005_3.mcap")
    result = recording.records["dynabarn.result"]
    assert result["outcome"] == info["outcome"] and int(result["n_ticks"]) == steps == env.episode.n_ticks
    assert recording.records["dynabarn.episode"]["planner"] == DRIVER
    assert len(recording.topic("/scan")) == steps and not recording.truncated  # a scan a period

    env.reset(options={"trial_seed": 4})
    for _ in range(3):
        env.step(np.array([0.2, 0.0], dtype=np.float32))
    env.reset(options={"trial_seed": 5})  # before trial 4 ended
    env.close()
    left = read_recording(tmp_path / "world_005_4.mcap")
    assert left.records["dynabarn.result"]["outcome"] == "error" and left.records["dynabarn.result"]["reason"] == LEFT
    assert int(left.records["dynabarn.result"]["n_ticks"]) == 3
    closed = read_recording(tmp_path / "world_005_5.mcap")  # closed before its first step: whole, as error
    assert closed.records["dynabarn.result"]["outcome"] == "error" and not closed.truncated


def test_observers_must_be_a_function_of_the_episode(env_class):
    with pytest.raises(ValueError, match="observers must be a function"):
        env_class(worlds=[5], observers=["not a factory"])
