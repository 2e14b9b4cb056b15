"""An expert acting beside the policy, through the environment's own step: `ExpertLabels`
wraps `DynaBARN-v0` so that after `reset` and after every `step` that does not end the
episode, a planner (the teacher: `predictive`, the oracle) acts on the same observation the
policy is given and its command comes back in `info["expert_action"]`, normalised as the
policy's action is (`spaces.command_to_action`).

DAgger labels its states so (`dagger_rollout`): who drives, the student or the teacher,
is then only which action is passed to `step`; an imitation user collects (observation,
expert action) pairs the same way, with any planner of the registry as the expert.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from dynabarn.planners.learned.spaces import command_to_action
from dynabarn.planners.registry import get_planner

EXPERT_ACTION = "expert_action"
"""The key of `info` that holds the expert's normalised action."""


class ExpertLabels(gymnasium.Wrapper):
    """`env` with `expert` (a planner name of the registry, with `config`) acting on every
    observation: its action in `info["expert_action"]`. The expert is made anew for each
    episode (`reset`), and finished with the episode's outcome.

    Args:
        env: a `DynaBARN-v0` environment (reset it with `options={"privileged": True}` for
            an expert that reads the obstacles' true states, e.g. `oracle_present`).
        expert: the planner that labels, by name (`get_planner`).
        config: its configuration.
    """

    def __init__(self, env: gymnasium.Env, expert: str, **config: Any) -> None:
        super().__init__(env)
        self.expert_name, self.expert_config = expert, config
        self.expert = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        observation, info = self.env.reset(seed=seed, options=options)
        self._finish("error")  # an episode left before its end
        self.expert = get_planner(self.expert_name, **self.expert_config)
        self.expert.reset(self.env.unwrapped.episode.info)
        return observation, {**info, EXPERT_ACTION: self._act()}

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        if terminated or truncated:
            self._finish(info.get("outcome") or "error")
        else:
            info = {**info, EXPERT_ACTION: self._act()}
        return observation, reward, terminated, truncated, info

    def stop(self, outcome: str) -> None:
        """End the expert's episode where the caller stops stepping before the episode's end
        (DAgger's cut episodes); the environment is left as it is."""
        self._finish(outcome)

    def close(self) -> None:
        self._finish("error")
        super().close()

    def _act(self) -> np.ndarray:
        """The expert's command for the environment's current observation, as an action."""
        return command_to_action(*self.expert.act(self.env.unwrapped.observation))

    def _finish(self, outcome: str) -> None:
        if self.expert is not None:
            expert, self.expert = self.expert, None
            expert.finish(outcome)
