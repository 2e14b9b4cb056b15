"""`DynaBARN-v0`: the benchmark as a Gymnasium environment.

## Description
A Clearpath Jackal must cross a DynaBARN world (Nair et al. 2022) from its spawn to the
goal among moving cylinders, with the observation of the paper's learned baselines: the
720-beam laser scan and the local goal from the Dijkstra global planner (Sec. IV-b,
Fig. 4). One step is one control period (0.1 s: 20 MuJoCo steps at 5 ms).

## Action space
`Box(-1, 1, (2,), float32)`, normalised; mapped linearly onto the paper's command ranges:

| num | action | min | max | unit after mapping |
|---|---|---|---|---|
| 0 | forward speed v = -0.5 + 1.25 (a0 + 1) | -1 | 1 | v in [-0.5, 2.0] m/s |
| 1 | turn rate w = 3.14 a1 | -1 | 1 | w in [-3.14, 3.14] rad/s |

## Observation space
`Box((722,), float32)`: 720 laser ranges [m] in [0.1, 30] (right to left over +-2.356 rad),
then the local goal (g_x, g_y) [m] in the robot frame, `lookahead` metres (default 2)
along the global plan (closer near the goal).

## Rewards
After the TD3 navigation work of the paper's group (progress, collision and success terms):
- `reward_progress` = 1.0 x (decrease of the cost-to-go to the goal on the static map) [per m];
- `reward_time` = -0.01 per step;
- `reward_collision` = -10 when the robot touches an obstacle or a wall;
- `reward_success` = +20 when the protocol judges the goal reached.
Each term is in `info`.

## Starting state
World drawn uniformly from the chosen set (and difficulty); trial seed drawn from the
environment's generator (sets the obstacles' clock offset and the laser noise); robot at
the protocol's spawn ((11, 0, yaw pi) for `barn`).

## Episode end
Terminated on success or collision; truncated on the protocol's time limit (100 s of
simulated time, 1,000 steps) or an error.

## Arguments
| parameter | type | default | description |
|---|---|---|---|
| world_set | str | "paper60" | paper60, dynabarn300, or a folder with index.json |
| difficulty | str or None | None | easy, medium, hard, or all |
| worlds | list[int] or None | None | explicit world ids (overrides difficulty) |
| protocol | str | "barn" | barn, paper2022 or a .json file |
| lookahead | float | 2.0 | local goal distance along the plan [m] |

## Version history
- v0: first version.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

from dynabarn.metrics import Outcome
from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.planners.learned.spaces import action_to_command, policy_input
from dynabarn.protocol import get_protocol
from dynabarn.robot import JACKAL
from dynabarn.sim import Episode, Simulation
from dynabarn.worldset import world_set as resolve_world_set

REWARD_PROGRESS = 1.0
REWARD_TIME = -0.01
REWARD_COLLISION = -10.0
REWARD_SUCCESS = 20.0


class DynaBARNEnv(gymnasium.Env):
    """DynaBARN navigation among moving obstacles (see the module docstring)."""

    metadata: ClassVar[dict] = {"render_modes": []}

    def __init__(
        self,
        world_set: str = "paper60",
        difficulty: str | None = None,
        worlds: list[int] | None = None,
        protocol: str = "barn",
        lookahead: float = 2.0,
    ) -> None:
        entries = resolve_world_set(world_set, list(worlds) if worlds is not None else None)
        if difficulty not in (None, "all"):
            entries = [e for e in entries if e[2] == difficulty]
        if not entries:
            raise ValueError(f"no worlds in set {world_set!r} with difficulty {difficulty!r}")
        self.entries = entries
        self.protocol = get_protocol(protocol)
        self.lookahead = float(lookahead)
        n = len(JACKAL.laser_angles())
        low = np.concatenate([np.full(n, JACKAL.laser_range_min), [-self.lookahead, -self.lookahead]])
        high = np.concatenate([np.full(n, JACKAL.laser_range_max), [self.lookahead, self.lookahead]])
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._sims: dict[str, Simulation] = {}
        self._planners: dict[str, GlobalPlanner] = {}
        self.episode: Episode | None = None

    def _observe(self) -> np.ndarray:
        obs = self.episode.observe()
        self._pose = obs.pose
        return policy_input(obs.scan, self._planner.local_goal_in_robot(obs.pose, self.lookahead), np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = options or {}
        if "world_index" in options:
            wid, file, difficulty = self.entries[int(options["world_index"]) % len(self.entries)]
        else:
            wid, file, difficulty = self.entries[int(self.np_random.integers(len(self.entries)))]
        trial = int(options.get("trial_seed", self.np_random.integers(2**31)))
        if file not in self._sims:
            self._sims[file] = Simulation(file)
            sim = self._sims[file]
            self._planners[file] = GlobalPlanner.for_robot(
                sim.walls, sim.goal, (JACKAL.length, JACKAL.width), np.array(sim.world.layout.cylinders).reshape(-1, 3)
            )
        sim = self._sims[file]
        self._planner = self._planners[file]
        self.episode = Episode(sim, self.protocol, seed=trial)
        observation = self._observe()
        self._cost_to_go = self._planner.cost_to_go(float(self._pose[0]), float(self._pose[1]))
        self._info = {"world": sim.world.name, "world_id": wid, "difficulty": difficulty, "trial_seed": trial}
        return observation, dict(self._info)

    def step(self, action):
        if self.episode is None:
            raise RuntimeError("call reset() before step()")
        v, w = action_to_command(action)
        outcome = self.episode.apply(v, w)
        observation = self._observe() if outcome is None else self._last_observation()
        ctg = self._planner.cost_to_go(float(self._pose[0]), float(self._pose[1]))
        progress = self._cost_to_go - ctg if math.isfinite(ctg) and math.isfinite(self._cost_to_go) else 0.0
        self._cost_to_go = ctg
        terms = {
            "reward_progress": REWARD_PROGRESS * progress,
            "reward_time": REWARD_TIME,
            "reward_collision": REWARD_COLLISION if outcome is Outcome.COLLISION else 0.0,
            "reward_success": REWARD_SUCCESS if outcome is Outcome.SUCCESS else 0.0,
        }
        terminated = outcome in (Outcome.SUCCESS, Outcome.COLLISION)
        truncated = outcome in (Outcome.TIMEOUT, Outcome.ERROR)
        info = {**self._info, **terms, "outcome": outcome.value if outcome else None, "time": self.episode.time}
        return observation, float(sum(terms.values())), terminated, truncated, info

    def _last_observation(self) -> np.ndarray:
        """After the episode ended: the final pose's observation, without a new scan."""
        ep = self.episode
        self._pose = ep.poses[ep.step].copy()
        g = self._planner.local_goal_in_robot(self._pose, self.lookahead)
        scan = np.clip(ep._obs.scan, JACKAL.laser_range_min, JACKAL.laser_range_max)
        return policy_input(scan, g, np.float32)
