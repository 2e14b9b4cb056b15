"""An expert acting through the environment's own step (`learn.expert.ExpertLabels`): its
action after every reset and step in `info["expert_action"]`, as DAgger labels its states."""

from __future__ import annotations

import numpy as np

from tests.conftest import require


def _env(expert: str):
    require("gymnasium", "learn")
    from dynabarn.learn.env import DynaBARNEnv
    from dynabarn.learn.expert import ExpertLabels

    return ExpertLabels(DynaBARNEnv(world_set="paper60"), expert)


def test_driving_by_the_experts_labels_is_driving_the_expert():
    """DWA's labels, passed back as the actions, reach the goal as DWA does in the runner,
    and are DWA's commands on the same observations (a second DWA fed them agrees)."""
    from dynabarn.planners import get_planner
    from dynabarn.planners.learned.spaces import command_to_action

    env = _env("dwa")
    _, info = env.reset(options={"world_index": 0, "trial_seed": 3})
    shadow = get_planner("dwa")
    shadow.reset(env.unwrapped.episode.info)
    while True:
        np.testing.assert_array_equal(info["expert_action"], command_to_action(*shadow.act(env.unwrapped.observation)))
        _, _, terminated, truncated, info = env.step(info["expert_action"])
        if terminated or truncated:
            break
    assert info["outcome"] == "success" and "expert_action" not in info  # no observation after the end
    assert env.expert is None  # finished with the episode
    env.close()


def test_an_expert_that_stops_labels_every_step_with_a_standstill():
    from dynabarn.planners.learned.spaces import command_to_action

    env = _env("stop")
    _, info = env.reset(options={"world_index": 5, "trial_seed": 0})
    for _ in range(5):
        np.testing.assert_array_equal(info["expert_action"], command_to_action(0.0, 0.0))
        _, _, terminated, truncated, info = env.step(info["expert_action"])
        assert not (terminated or truncated)
    env.stop("cut")
    assert env.expert is None
    env.close()
