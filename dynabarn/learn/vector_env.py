"""`DynaBARNVectorEnv`: many DynaBARN-v0 worlds stepped at once (Gymnasium's `VectorEnv`).

`num_envs` sub-environments, each exactly a `DynaBARNEnv` (same worlds, seeds, dynamics,
rewards and observations: a test steps both side by side), split over `workers`
processes (default: one per core, at most 2 here): this one steps the first share itself
while the others (spawned) step theirs. Inside a process the worlds advance
together (`WorldBatch`):

1. each world's physics period: MuJoCo's C step, 20 per control period;
2. every world's observation at once (`sim.batch_observe`: the obstacles placed, the 720
   rays in one vectorised closed-form pass for worlds of the paper's kind, each world's
   laser noise from its own generator);
3. the local goals of all worlds at once, then each world's reward, as the single
   environment does.

The scan agrees with the single environment's to the laser's 1 mm grid (`sim.batch_observe`).
Autoreset is Gymnasium's default (`NEXT_STEP`): the step after an episode ends resets that
world and returns its first observation.
Workers are started with `spawn`, write their observations into a buffer shared with this
process and send the rest over pipes, and end with the environment (or with their parent:
they exit when the pipe closes). A fixed set's worlds are compiled in every process when
the environment is made (paper60: 0.3 s), not in the steps that first meet them.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import time
from typing import Any, ClassVar

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from dynabarn.learn.env import DynaBARNEnv
from dynabarn.learn.shared_worlds import SHARED_WORLDS, shared_world
from dynabarn.planners.learned.spaces import action_to_command, checked_actions
from dynabarn.planners.local_goal_batch import LocalGoalBatch
from dynabarn.processes import safe_path_for_children, usable_cores, worker_start
from dynabarn.sim.batch_observe import BatchObserver


class WorldBatch:
    """Sub-environments stepped together in one process."""

    def __init__(self, n: int, env_kwargs: dict, obs: np.ndarray | None = None) -> None:
        self.envs = [DynaBARNEnv(**env_kwargs) for _ in range(n)]
        for env in self.envs:
            env.batched = True  # their loops leave the observation to `_observe`, all worlds at once
        # Every step writes every row (a new episode's first observation, a running one's
        # next, an ended one's last), here or into the parent's shared buffer.
        self.obs = np.zeros((n, *self.envs[0].observation_space.shape), np.float32) if obs is None else obs
        self.needs_reset = np.ones(n, dtype=bool)
        self._observer = BatchObserver()
        self._local_goals = LocalGoalBatch(capacity=2 * n + 4)  # a world that comes back keeps its plan
        # A fixed set's worlds compiled and planned here, now (paper60: 0.3 s): otherwise
        # each is compiled in the step that first meets it, a 5 ms stall of the whole batch
        # (and, across processes, of the other share waiting for it).
        first = self.envs[0]
        if first.procedural is None and len(first.entries) <= SHARED_WORLDS:
            for _, file, _ in first.entries:
                shared_world(file)

    def reset(self, seeds: list[int | None], options: dict | None) -> tuple[np.ndarray, list[dict]]:
        for env, seed in zip(self.envs, seeds, strict=True):
            env.begin(seed, options)
        obs = self.obs
        fresh = list(range(len(self.envs)))
        self._observe(fresh, obs)
        infos = [self.envs[i].started(obs[i])[1] for i in fresh]
        self.needs_reset[:] = False
        return obs, _infos(infos)

    def step(self, actions: np.ndarray):
        n = len(self.envs)
        obs = self.obs
        rewards, terminated, truncated = np.zeros(n), np.zeros(n, bool), np.zeros(n, bool)
        infos: list[dict] = [{} for _ in range(n)]
        running, fresh = [], []
        v, w = action_to_command(np.asarray(actions).T)  # elementwise: each world's own bits
        for i, env in enumerate(self.envs):
            if self.needs_reset[i]:  # Gymnasium's NEXT_STEP autoreset: a new episode, observed below
                env.begin(None, None)
                fresh.append(i)
                continue
            outcome = env.loop.period(float(v[i]), float(w[i]))
            if outcome is None:
                running.append(i)
            else:
                obs[i], rewards[i], terminated[i], truncated[i], infos[i] = env.conclude(
                    outcome, env.final_observation()
                )
        # New episodes' first observations and the running ones' next, in one batch.
        if running or fresh:
            self._observe(sorted(running + fresh), obs)
        for i in running:
            _, rewards[i], terminated[i], truncated[i], infos[i] = self.envs[i].conclude(None, None)
        for i in fresh:
            infos[i] = self.envs[i].started(obs[i])[1]
        self.needs_reset = terminated | truncated
        # The infos as Gymnasium's arrays here, in the worker: the parent only joins them.
        return obs, rewards, terminated, truncated, _infos(infos)

    def _observe(self, running: list[int], obs: np.ndarray) -> None:
        """The observations of the worlds `running` (stepped or just started) into obs's rows:
        the episodes observed together (`sim.batch_observe`), then the local goals, all at once."""
        envs = [self.envs[i] for i in running]
        observations = self._observer.observe([env.episode for env in envs])
        poses = np.array([env.seen(o).pose for env, o in zip(envs, observations, strict=True)])
        goals = self._local_goals.local_goals_in_robot([env.global_planner for env in envs], poses, envs[0].lookahead)
        obs[running, : len(observations[0].scan)] = [o.scan for o in observations]
        obs[running, len(observations[0].scan) :] = goals

    def close(self) -> None:
        for env in self.envs:
            env.close()


SPIN_WAIT = 0.005
"""[s] a process waiting for the other's share polls its pipe this long before it sleeps."""


def _spin(conn) -> None:
    """Poll `conn` until a message is there or SPIN_WAIT has passed (then recv blocks).
    A step's shares take ~3 ms each: a process that sleeps on its pipe meanwhile lets its
    virtual CPU halt, and waking it cost ~0.4 ms per step (32 worlds: 9,100-9,500 control
    steps per second blocking, 10,000-10,200 polling). `sched_yield` gives the core to any
    other runnable process (a loaded machine loses nothing to the poll)."""
    end = time.perf_counter() + SPIN_WAIT
    while not conn.poll(0) and time.perf_counter() < end:
        os.sched_yield()


def _ended(k: int) -> RuntimeError:
    return RuntimeError(
        f"worker process {k} ended (its error, if any, is printed above); a script that makes this "
        'environment with workers needs Python\'s `if __name__ == "__main__":` guard'
    )


def _worker(
    conn, n: int, env_kwargs: dict, shared, rows: tuple[int, int], obs_dim: int, parent: int | None = None
) -> None:
    if parent is not None:
        worker_start(parent)  # ends with its parent, even one killed with SIGKILL
    obs = np.frombuffer(shared, dtype=np.float32).reshape(-1, obs_dim)[rows[0] : rows[1]]
    batch = WorldBatch(n, env_kwargs, obs)
    try:
        while True:
            try:
                _spin(conn)
                cmd, payload = conn.recv()
            except (EOFError, OSError):  # the parent is gone
                return
            # The observations are in the shared buffer: only the small values go by pipe.
            reply = None
            if cmd == "step":
                reply = batch.step(payload)[1:]
            elif cmd == "reset":
                reply = batch.reset(*payload)[1:]
            try:
                conn.send(reply)
            except OSError:  # the parent died while this step ran (a broken pipe): nobody to answer
                return
            if cmd == "close":
                return
    finally:
        batch.close()


class DynaBARNVectorEnv(VectorEnv):
    """`num_envs` DynaBARN-v0 worlds stepped by `workers` processes: this one and
    `workers - 1` spawned ones (0 or 1: all in this process).

    Args: `num_envs`, `workers` (default: one per usable core, at most `num_envs`), and every keyword of
    `DynaBARNEnv` but rendering (`world_set`, `split`, `split_seed`, `difficulty`,
    `worlds`, `protocol`, `lookahead`). `reset(seed=s)` seeds world i with s + i.

    `backend="warp"` (the `gpu` extra) gives the Warp backend instead, for training: a
    `WarpVectorEnv` on `device` ("cuda", "cuda:1" or Warp's "cpu") over the same worlds
    (a set, a difficulty, chosen worlds, or a procedural split's first `procedural_worlds`),
    with PyTorch tensors in and out and same-step autoreset; `seed` draws its trials.
    `backend="c"` (the default) is MuJoCo's C engine, here, with numpy.
    """

    metadata: ClassVar[dict[str, Any]] = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __new__(cls, num_envs: int = 8, *, backend: str = "c", device: str = "cpu", **kwargs):
        if backend == "warp":
            return warp_vector_env(num_envs, device=device, **kwargs)
        if backend != "c":
            raise ValueError(f"backend {backend!r}: use 'c' (MuJoCo's C engine) or 'warp' (MuJoCo Warp, for training)")
        if device != "cpu":
            raise ValueError(f"device {device!r}: the C engine runs on the CPU; a GPU is the Warp backend's")
        return super().__new__(cls)

    def __init__(
        self,
        num_envs: int = 8,
        *,
        workers: int | None = None,
        max_episode_steps: int | None = None,
        backend: str = "c",
        device: str = "cpu",
        **env_kwargs,
    ) -> None:
        # `gymnasium.make_vec` passes the registered max_episode_steps; the protocol always
        # ends an episode first (see DynaBARNEnv's docstring), so it is only recorded.
        self.max_episode_steps = max_episode_steps
        if not (isinstance(num_envs, int) and num_envs >= 1):
            raise ValueError(f"num_envs must be a whole number >= 1, got {num_envs!r}")
        if "render_mode" in env_kwargs:
            raise ValueError("the vector environment does not render; use DynaBARNEnv for pictures")
        workers = min(num_envs, usable_cores()) if workers is None else workers
        if isinstance(workers, bool) or not (isinstance(workers, int) and 0 <= workers <= num_envs):
            raise ValueError(f"workers must be a whole number in [0, num_envs], got {workers!r}")
        probe = DynaBARNEnv(**env_kwargs)  # checks the arguments here, with one clear error
        self.single_observation_space = probe.observation_space
        self.single_action_space = probe.action_space
        probe.close()
        self.num_envs = num_envs
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.workers = workers
        sizes = [len(part) for part in np.array_split(np.arange(num_envs), max(1, workers))]
        self._sizes, self._slices = sizes, np.cumsum([0, *sizes])
        ctx = mp.get_context("spawn")
        safe_path_for_children()  # a spawned worker starts as `python -c`: never from the current folder
        # Every share writes its observations into one buffer shared with the workers (a
        # pipe would pickle 46 kB per step and share); step returns a copy of it.
        obs_dim = int(np.prod(self.single_observation_space.shape))
        self._shared = ctx.RawArray(ctypes.c_float, num_envs * obs_dim)
        self._obs = np.frombuffer(self._shared, dtype=np.float32).reshape(num_envs, obs_dim)
        # This process steps the first share itself while the others step theirs: on 2 cores,
        # 2 processes and no third one waking between them (measured: +7 % over 2 spawned).
        self._local = WorldBatch(sizes[0], env_kwargs, self._obs[: sizes[0]])
        self._conns: list = []
        self._procs: list = []
        for k, n in enumerate(sizes[1:], start=1):
            parent, child = ctx.Pipe()
            rows = (int(self._slices[k]), int(self._slices[k + 1]))
            args = (child, n, env_kwargs, self._shared, rows, obs_dim, os.getpid())
            p = ctx.Process(target=_worker, args=args, daemon=True)
            p.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(p)
        self.closed = False

    def _parts(self, cmd: str, payloads: list) -> list:
        """Each share's answer to `cmd` but its observations (in the shared buffer): the
        others' sent first, then this process's own."""
        for k, (conn, payload) in enumerate(zip(self._conns, payloads[1:], strict=True), start=1):
            try:
                conn.send((cmd, payload))
            except OSError:
                raise _ended(k) from None
        mine = self._local.reset(*payloads[0]) if cmd == "reset" else self._local.step(payloads[0])
        parts = [mine[1:]]
        for k, conn in enumerate(self._conns, start=1):
            try:
                _spin(conn)
                parts.append(conn.recv())
            except (EOFError, OSError):
                raise _ended(k) from None
        return parts

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if self.closed:
            raise RuntimeError("the environment is closed; make a new one")
        seeds = [None if seed is None else seed + i for i in range(self.num_envs)]
        payloads = [(seeds[a:b], options) for a, b in zip(self._slices[:-1], self._slices[1:], strict=True)]
        parts = self._parts("reset", payloads)
        return self._obs.copy(), _join([p[0] for p in parts], self._sizes)

    def step(self, actions):
        if self.closed:
            raise RuntimeError("the environment is closed; make a new one")
        actions = checked_actions(actions, self.num_envs).astype(np.float32)
        payloads = [actions[a:b] for a, b in zip(self._slices[:-1], self._slices[1:], strict=True)]
        parts = self._parts("step", payloads)
        rew, term, trunc = (np.concatenate([p[k] for p in parts]) for k in range(3))
        return self._obs.copy(), rew, term, trunc, _join([p[3] for p in parts], self._sizes)

    def close_extras(self, **kwargs) -> None:
        self._local.close()
        for conn in self._conns:
            try:
                conn.send(("close", None))
                conn.recv()
            except (EOFError, OSError, BrokenPipeError):
                pass
            conn.close()
        for p in self._procs:
            p.join(timeout=10)
            if p.is_alive():
                p.kill()
        self._conns, self._procs = [], []


INFO_KEYS = ("is_success", "world_id", "difficulty", "trial_seed", "outcome")
INFO_KINDS = {"is_success": bool, "world_id": np.int64, "trial_seed": np.int64}
"""Their array types (object for the rest: names and outcomes)."""


PROCEDURAL_WORLDS = 64
"""Training worlds a Warp batch draws from a procedural split (`procedural_worlds`)."""


def warp_vector_env(
    num_envs: int,
    *,
    device: str,
    workers: int | None = None,
    max_episode_steps: int | None = None,
    procedural_worlds: int = PROCEDURAL_WORLDS,
    seed: int = 0,
    **env_kwargs,
):
    """`DynaBARNVectorEnv(backend="warp")`: the worlds `DynaBARNEnv` would draw from, in a
    `WarpVectorEnv` on `device`. A procedural split (`split="train"`) gives its first
    `procedural_worlds` worlds (the same on any machine for the same split and seed), drawn
    once: a Warp batch's worlds are compiled into its model when it is made."""
    from dynabarn.learn.warp_env import WarpVectorEnv  # the `gpu` extra: only when asked for

    if workers is not None:
        raise ValueError("workers: the Warp backend steps every world on its device, in this process")
    if "render_mode" in env_kwargs:
        raise ValueError("the vector environment does not render; use DynaBARNEnv for pictures")
    if not (isinstance(procedural_worlds, int) and 1 <= procedural_worlds <= 4096):
        raise ValueError(f"procedural_worlds must be a whole number in [1, 4096], got {procedural_worlds!r}")
    probe = DynaBARNEnv(**env_kwargs)  # the same worlds, and the same one-line refusals
    try:
        if probe.procedural is not None:
            probe.procedural.keep = procedural_worlds  # every file kept until the batch is made
            files = [str(probe.procedural.world(k).path) for k in range(procedural_worlds)]
        else:
            files = [file for _, file, _ in probe.entries]
        return WarpVectorEnv(
            files,
            num_envs,
            device=device,
            lookahead=probe.lookahead,
            protocol=env_kwargs.get("protocol", "barn"),
            seed=seed,
        )
    finally:
        probe.close()  # a procedural split's files go with it: the batch holds what it needs


def _infos(items: list[dict]) -> dict:
    """Gymnasium's vector info: one array per key, and `_key` saying which worlds have it."""
    out: dict[str, np.ndarray] = {}
    for key in INFO_KEYS:
        have = np.array([key in i for i in items])
        if not have.any():
            continue
        values = [i.get(key) for i in items]
        kind = INFO_KINDS.get(key, object)
        out[key] = np.array([v if v is not None or kind is object else 0 for v in values], dtype=kind)
        out["_" + key] = have
    return out


def _join(parts: list[dict], sizes: list[int]) -> dict:
    """The workers' info arrays as one (a key a worker lacks: its worlds do not have it)."""
    out: dict[str, np.ndarray] = {}
    for key in INFO_KEYS:
        if not any(key in p for p in parts):
            continue
        kind = INFO_KINDS.get(key, object)
        pairs = list(zip(parts, sizes, strict=True))
        out[key] = np.concatenate([p.get(key, np.zeros(n, dtype=kind)) for p, n in pairs])
        out["_" + key] = np.concatenate([p.get("_" + key, np.zeros(n, bool)) for p, n in pairs])
    return out
