"""`WarpVectorEnv`: DynaBARN-v0's episodes of one world, thousands at once on a Warp device.

The same task as `DynaBARNEnv` (its observation, action, rewards and ends; `learn.env`'s
docstring defines them), with every world's step on the device (`learn.warp_worlds`)
and PyTorch tensors in and out, so a learner on the same GPU never copies through the host:

- the action (num_envs, 2) in [-1, 1] -> the command (`action_to_command`'s arithmetic);
- one control period of every world, judged by the protocol;
- the rewards: progress along the static map's cost-to-go, time, collision, success;
- worlds that ended restart in the same step (mjlab's and MuJoCo Playground's autoreset):
  `info["final_observation"]` holds their last observation (the final pose's local goal
  with the period's scan, as `DynaBARNEnv.final_observation`), the observation returned
  is the new episode's first;
- the observation: the 720 ranges, then the local goal `lookahead` metres along the
  world's Dijkstra plan in the robot frame. The plan's first cells from every cell of the
  map are tabled once on the host (`GlobalPlanner.plan_suffix`: a local goal depends on
  the robot's cell and its position), so the walk along them is one kernel.

Each environment's episodes draw their trial seeds from its own generator (a seed
sequence spawned per environment), tabled `TRIALS` at a time on the device: the clock
offset and the laser's noise of each trial come from it, as `Episode`'s do. For training
only; evaluation stays on the C engine.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium.vector import AutoresetMode

from dynabarn.errors import DynabarnError
from dynabarn.learn import warp_env_kernels as kernels
from dynabarn.learn.gym_spaces import ACTION_SPACE, observation_space
from dynabarn.learn.shared_worlds import shared_world
from dynabarn.learn.warp_worlds import WarpWorlds, require_warp
from dynabarn.planners.global_planner import BOUNDS
from dynabarn.robot import JACKAL
from dynabarn.sim_config import trial_clock_offset

try:
    import warp as wp
except ImportError:
    wp = None

TRIALS = 256
"""Trials tabled per environment; its episodes go round them (a new table: `reset(seed=...)`)."""


def _device_actions(actions):
    """Actions as a Warp array: a PyTorch tensor shared (no copy when float32 and
    contiguous on the device), anything else copied in."""
    try:
        import torch
    except ImportError:
        torch = None
    if torch is not None and isinstance(actions, torch.Tensor):
        return wp.from_torch(actions.detach().to(torch.float32).contiguous())
    return wp.array(np.asarray(actions, dtype=np.float32))


class WarpVectorEnv:
    """`num_envs` episodes of DynaBARN-v0 on a Warp device, with PyTorch tensors in and out
    (see the module docstring): of one world file, or of a list of them (each episode in one
    drawn from the environment's own generator, as `DynaBARNEnv` draws its worlds).
    `DynaBARNVectorEnv(..., backend="warp")` makes one from a set's name."""

    metadata: ClassVar[dict[str, Any]] = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        world_file: str | list[str],
        num_envs: int,
        *,
        device: str = "cpu",
        lookahead: float = 2.0,
        protocol: str = "barn",
        laser_noise: bool = True,
        seed: int = 0,
        graph: bool | None = None,
    ) -> None:
        require_warp()
        if not 0.1 <= lookahead <= 30.0:
            raise DynabarnError(f"lookahead {lookahead!r}: a number of metres in [0.1, 30]")
        self.num_envs, self.device, self.lookahead = num_envs, device, float(lookahead)
        self.worlds = WarpWorlds(world_file, num_envs, device=device, protocol=protocol, laser_noise=laser_noise)
        self.world_files = [str(p) for p in self.worlds.library.paths]
        """The worlds each environment's episodes are drawn from (uniformly, per trial)."""
        planners = [shared_world(file)[1] for file in self.world_files]
        f = planners[0].field
        self._spawn = np.asarray(self.worlds.protocol.spawn, dtype=np.float32)
        n = num_envs
        with wp.ScopedDevice(device):
            self._plan = kernels.PlanMap()
            self._plan.pred = wp.array(np.stack([pl.field.pred_array.ravel() for pl in planners]), dtype=int)
            self._plan.cost = wp.array(
                np.stack([pl.field.cost.ravel() for pl in planners]).astype(np.float32), dtype=float
            )
            self._plan.goal = wp.array(np.array([pl.goal for pl in planners], dtype=np.float32), dtype=wp.vec2)
            self._plan.origin = wp.vec2(BOUNDS[0], BOUNDS[2])
            self._plan.resolution = planners[0].resolution
            self._plan.nx, self._plan.ny, self._plan.lookahead = f.nx, f.ny, self.lookahead
            self._plan.cells = int(np.floor(self.lookahead / planners[0].resolution)) + 3  # `plan_suffix`'s
            self._spawns = wp.array(np.tile(self._spawn, (n, 1)), dtype=wp.vec3)
            self._last_cost = wp.zeros(n, dtype=float)
            self._episodes = wp.zeros(n, dtype=int)
            self._mask, self._offset, self._seed, self._world = (
                wp.zeros(n, dtype=int),
                wp.zeros(n, dtype=float),
                wp.zeros(n, dtype=int),
                wp.zeros(n, dtype=int),
            )
            self._commands = wp.zeros(n, dtype=wp.vec2)
            self._actions = wp.zeros((n, 2), dtype=float)
            self.reward = wp.zeros(n, dtype=float)
            self.terminated, self.truncated = wp.zeros(n, dtype=int), wp.zeros(n, dtype=int)
            self.success = wp.zeros(n, dtype=int)
            self.obs = wp.zeros((n, self.worlds.n_beams + 2), dtype=float)
            self.final_obs = wp.zeros((n, self.worlds.n_beams + 2), dtype=float)
        self._limits = wp.vec3(JACKAL.v_min, JACKAL.v_max, JACKAL.w_max)
        self.single_observation_space, self.single_action_space = observation_space(self.lookahead), ACTION_SPACE
        self.graph = wp.get_device(device).is_cuda if graph is None else bool(graph)
        """A period replayed as a CUDA graph (default on a GPU): Python launches dozens of
        kernels per physics step, which a graph replaces with one launch per period."""
        self._graph = None
        self._new_trials(seed)

    def _new_trials(self, seed: int) -> None:
        """Each environment's next `TRIALS` trials from its own generator: the trial seeds,
        then the world each is played in (an index into `world_files`)."""
        trials, worlds = [], []
        for stream in np.random.SeedSequence(seed).spawn(self.num_envs):
            rng = np.random.default_rng(stream)
            trials.append(rng.integers(2**31, size=TRIALS))
            worlds.append(rng.integers(len(self.world_files), size=TRIALS))
        self._table(np.stack(trials), np.stack(worlds))

    def schedule(self, trials: np.ndarray, worlds: np.ndarray) -> None:
        """Each environment's coming episodes chosen by its caller instead of drawn: row w of
        `trials` (trial seeds) and `worlds` (indices into `world_files`), both (num_envs, T),
        from the next `reset` on (without a seed: a seed draws anew). DAgger's collection
        plays its episodes so, each in its world and trial."""
        trials, worlds = np.asarray(trials, dtype=np.int64), np.asarray(worlds, dtype=np.int64)
        if trials.shape != worlds.shape or trials.ndim != 2 or trials.shape[0] != self.num_envs:
            raise DynabarnError(f"schedule: trials and worlds of shape ({self.num_envs}, T) each")
        if worlds.min() < 0 or worlds.max() >= len(self.world_files) or trials.min() < 0 or trials.max() >= 2**31:
            raise DynabarnError("schedule: world indices into world_files, trial seeds in [0, 2**31)")
        self._table(trials, worlds)

    def _table(self, trials: np.ndarray, worlds: np.ndarray) -> None:
        """The coming trials (seeds, worlds), with their clock offsets (`trial_clock_offset`,
        as an `Episode` draws it), on the device."""
        self.trials, self.trial_worlds = trials, worlds
        offsets = np.vectorize(lambda t: trial_clock_offset(int(t)))(trials)
        with wp.ScopedDevice(self.device):
            self._trial_offsets = wp.array(offsets.astype(np.float32), dtype=float)
            self._trial_seeds = wp.array(trials.astype(np.int32), dtype=int)
            self._trial_worlds = wp.array(worlds.astype(np.int32), dtype=int)

    def cut(self, mask) -> None:
        """End the episodes of the environments in `mask` (num_envs,) before the protocol
        does (a caller's step limit): each starts its next trial; their rows of the
        observation (`obs`) are then those episodes' first."""
        with wp.ScopedDevice(self.device):
            wp.launch(
                kernels.cut_episodes,
                self.num_envs,
                inputs=[wp.array(np.asarray(mask, dtype=np.int32)), self.worlds.outcome, self._episodes],
            )
            self._restart_ended()

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Every environment's first episode (its trials drawn anew from `seed` when given),
        as Gymnasium's `VectorEnv.reset`: the observations (num_envs, 722), a PyTorch tensor
        on the device, and an info with each environment's world (`world`, an index into
        `world_files`). No options are taken."""
        if options:
            raise ValueError(f"the Warp backend's reset takes no options, got {sorted(options)}")
        if seed is not None:
            self._new_trials(seed)
        with wp.ScopedDevice(self.device):
            self._episodes.zero_()
            self.worlds.outcome.fill_(1)  # every world "ended": all restart on their first trial
            self._restart_ended()
        return wp.to_torch(self.obs), {"world": wp.to_torch(self.worlds.world_of)}

    def close(self) -> None:
        """Nothing to end: no process or thread of its own (Gymnasium's `close`)."""

    def step(self, actions):
        """One control period of every environment: `actions` (num_envs, 2) in [-1, 1] (a
        PyTorch tensor on the device, or anything `wp.array` takes); returns observations,
        rewards, terminated, truncated (PyTorch tensors) and `info` with the final
        observations of the environments that ended (rows valid where either is set) and
        which of them reached the goal (`success`)."""
        with wp.ScopedDevice(self.device):
            wp.copy(self._actions, _device_actions(actions))
            if not self.graph:
                self._period()
            else:  # CUDA: the whole period recorded once as a graph, then replayed in one launch
                if self._graph is None:
                    with wp.ScopedCapture() as capture:
                        self._period()
                    self._graph = capture.graph
                wp.capture_launch(self._graph)
        info = {"final_observation": wp.to_torch(self.final_obs), "success": wp.to_torch(self.success).bool()}
        return (
            wp.to_torch(self.obs),
            wp.to_torch(self.reward),
            wp.to_torch(self.terminated).bool(),
            wp.to_torch(self.truncated).bool(),
            info,
        )

    def _period(self) -> None:
        """A control period's launches, on fixed buffers (what a CUDA graph records)."""
        n = self.num_envs
        wp.launch(kernels.actions_to_commands, n, inputs=[self._actions, self._limits], outputs=[self._commands])
        self.worlds.step(self._commands, observe=False)  # the final observations take this period's scan
        wp.launch(kernels.conclude_period, n, inputs=[*self._ended_inputs()])
        self._restart_ended()

    def _ended_inputs(self) -> list:
        w = self.worlds
        ended = [self.reward, self.terminated, self.truncated, self.success, self.final_obs, self._episodes]
        return [w.outcome, w.end_pose, w.d.qpos, w.scan, self._plan, w.world_of, self._last_cost, *ended]

    def _restart_ended(self) -> None:
        """Worlds whose episode ended start their next trial; then every observation."""
        w = self.worlds
        wp.launch(
            kernels.next_trials,
            self.num_envs,
            inputs=[w.outcome, self._episodes, self._trial_offsets, self._trial_seeds, self._trial_worlds],
            outputs=[self._mask, self._offset, self._seed, self._world],
        )
        w.restart(self._mask, self._spawns, self._offset, self._seed, self._world)
        w.observe()
        wp.launch(
            kernels.observe_envs,
            self.num_envs,
            inputs=[w.d.qpos, w.scan, self._plan, w.world_of, self._mask, self._last_cost],
            outputs=[self.obs],
        )  # fmt: skip
