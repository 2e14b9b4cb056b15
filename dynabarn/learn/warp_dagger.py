"""DAgger's collection on the Warp backend (`dynabarn-train dagger --env-backend warp`).

The episodes of an iteration are those of the C engine's collection (`dagger_rollout`):
episode k in the split's world k, on the trial drawn from `SeedSequence([seed, k, 0])`, the
same generator then tossing, step by step, the coin that lets the teacher drive with
probability beta. What moves is where they are stepped: every episode's physics, contacts,
judgement and scan run in one `WarpVectorEnv` batch on the device, the iteration's worlds
padded into its model, each environment playing its share of the episodes in turn.

The student's features (the laser tracker among them) and the teacher (a search) are the
CPU's, as in the C collection, spread over `workers` hosts (`learn.warp_dagger_hosts`: this
process and spawned ones, each with a slice of the environments). Each period the batch's
state comes to the host once (scans, poses, velocities, steps) into buffers the hosts
share; a mirror `Episode` per environment (the world's C model, not stepped) turns it into
the `Observation` the C engine would make: the privileged obstacles from the same
schedules, the same velocity, time and goal. The student acts for every environment in one
forward pass on the device. So the data differ from the C collection's only by the Warp
backend's float32 path and its own draw of the laser's noise.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os

import numpy as np
import torch

from dynabarn.learn.dagger_rollout import EpisodeData, episode_draws
from dynabarn.learn.env import DynaBARNEnv
from dynabarn.learn.warp_dagger_hosts import Buffers, Host, Plan, end_codes, serve
from dynabarn.planners.learned.student import StudentActor
from dynabarn.processes import safe_path_for_children


def collect_on_warp(
    cfg, ks, *, beta: float, actor: StudentActor | None, device: str, num_envs: int, workers: int = 1
) -> list[EpisodeData]:
    """The labelled training episodes of worlds `ks` of the split (`dagger_rollout.episode`'s,
    with the teacher driving with probability beta and labelling every state), stepped on
    `device` by at most `num_envs` environments, their CPU side on `workers` hosts; in the
    order of ks."""
    from dynabarn.learn.warp_env import WarpVectorEnv  # the `gpu` extra

    ks = list(ks)
    probe = DynaBARNEnv(
        split="train", split_seed=cfg.seed, split_profile_sets=tuple(cfg.profile_sets), protocol=cfg.protocol
    )
    try:  # the split's files live as long as the probe: every host compiles its mirrors from them
        probe.procedural.keep = len(ks)
        drawn = [probe.procedural.world(k) for k in ks]
        n = min(num_envs, len(ks))
        env = WarpVectorEnv([str(d.path) for d in drawn], n, device=device, protocol=cfg.protocol)
        trials = [episode_draws(cfg, "train", k)[0] for k in ks]
        plan = Plan(
            ks=ks,
            files=[str(d.path) for d in drawn],
            difficulties=[d.difficulty for d in drawn],
            fingerprints=[d.fingerprint for d in drawn],
            trials=trials,
            queues=[list(range(w, len(ks), n)) for w in range(n)],
        )
        # Environment w plays episodes w, w + n, ...; one that has played them all repeats
        # its last, unrecorded, until the others are done.
        width = max(len(q) for q in plan.queues) + 1
        table = np.array([[q[min(j, len(q) - 1)] for j in range(width)] for q in plan.queues])
        env.schedule(np.array(trials)[table], table)
        return _run(cfg, plan, env, actor, beta, workers)
    finally:
        probe.close()


def _run(cfg, plan: Plan, env, actor, beta: float, workers: int) -> list[EpisodeData]:
    n, size = env.num_envs, cfg.features().size()
    ctx = mp.get_context("spawn")
    buffers = Buffers.allocate(ctx, n, size)
    slices = [range(int(s[0]), int(s[-1]) + 1) for s in np.array_split(np.arange(n), min(workers, n))]
    conns, procs = [], []
    safe_path_for_children()  # a spawned host starts as `python -c`: never from the current folder
    try:
        for envs in slices[1:]:
            parent, child = ctx.Pipe()
            args = (child, cfg, plan, envs, buffers.raw, n, size, beta, actor is not None, os.getpid())
            p = ctx.Process(target=serve, args=args, daemon=True)
            p.start()
            child.close()
            conns.append(parent)
            procs.append(p)
        local = Host(cfg, plan, slices[0], buffers, beta=beta, student=actor is not None)
        for conn in conns:
            _answer(conn)  # "ready": its mirrors compiled
        return _periods(env, buffers, local, conns, actor, plan.ks)
    finally:
        for conn in conns:
            with contextlib.suppress(OSError):  # a host that died has nothing to stop
                conn.send("stop")
        for p in procs:
            p.join(timeout=10)
            if p.is_alive():
                p.kill()


def _ask(local: Host, conns: list, command: str) -> list:
    """Every host's answer to `command`: the others asked first, then this process's own."""
    for conn in conns:
        conn.send(command)
    answers = [getattr(local, command)()]
    return answers + [_answer(conn) for conn in conns]


def _answer(conn):
    try:
        return conn.recv()
    except (EOFError, OSError):
        raise RuntimeError("a host of the Warp collection ended before its work did (see its error above)") from None


def _periods(env, b: Buffers, local: Host, conns: list, actor, ks: list[int]) -> list[EpisodeData]:
    obs, _ = env.reset()
    worlds = env.worlds
    results: dict[int, EpisodeData] = {}
    while b.active.any():
        b.scans[:] = obs[:, :720].cpu().numpy()
        b.qpos[:] = worlds.d.qpos.numpy()[:, :3]
        b.qvel[:] = worlds.d.qvel.numpy()[:, :3]
        b.steps[:] = worlds.steps.numpy()
        _ask(local, conns, "observe")
        actions = np.where(b.active[:, None] != 0, b.teacher, 0.0).astype(np.float32)
        if actor is not None:
            with torch.no_grad():
                x = torch.from_numpy(b.xs).to(next(actor.parameters()).device)
                student = actor.act(x).cpu().numpy()
            drives = (b.active != 0) & (b.coin == 0)
            actions[drives] = student[drives]
        obs, _, terminated, truncated, info = env.step(torch.from_numpy(actions).to(obs.device))
        success = info["success"].cpu().numpy()
        terminated, truncated = terminated.cpu().numpy(), truncated.cpu().numpy()
        b.ends[:] = end_codes(terminated, truncated, success)
        for done in _ask(local, conns, "settle"):
            results.update((e.k, e) for e in done)
        if b.cut.any():
            env.cut(b.cut != 0)  # their rows of `obs` (a view on the batch's buffer) start their next episodes
    return [results[k] for k in ks]
