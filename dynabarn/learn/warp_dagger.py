"""DAgger's collection on the Warp backend (`dynabarn-train dagger --env-backend warp`).

The episodes of an iteration are those of the C engine's collection (`dagger_rollout`):
episode k in the split's world k, on the trial drawn from `SeedSequence([seed, k, 0])`, the
same generator then tossing, step by step, the coin that lets the teacher drive with
probability beta. What moves is where they are stepped: every episode's physics, contacts,
judgement and scan run in one `WarpVectorEnv` batch on the device, the iteration's worlds
padded into its model, each environment playing its share of the episodes in turn.

The student and its teacher are the CPU's, as in the C collection: the student's features
hold the laser tracker, and the teacher (`predictive` or the oracle) is a search. Each
period the batch's state comes to the host once (scans, poses, velocities, steps), and a
mirror `Episode` per environment (the world's C model, not stepped) turns a world's state
into the `Observation` the C engine would make of it: the privileged obstacles from the
same schedules, the same velocity, time and goal. The student acts for every environment
in one forward pass. So the data differ from the C collection's only by the Warp backend's
float32 path and its own draw of the laser's noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from dynabarn.learn.dagger_rollout import EpisodeData
from dynabarn.learn.env import DynaBARNEnv
from dynabarn.learn.shared_worlds import shared_world
from dynabarn.learn.split import DrawnWorld
from dynabarn.planners.learned.features import Features
from dynabarn.planners.learned.spaces import command_to_action
from dynabarn.planners.learned.student import StudentActor
from dynabarn.planners.registry import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.sim.episode import Episode


@dataclass
class _Running:
    """One environment's episode in progress: its mirror, features, teacher and data."""

    k: int
    drawn: DrawnWorld
    mirror: Episode
    features: Features
    teacher: object
    rng: np.random.Generator
    xs: list = field(default_factory=list)
    ys: list = field(default_factory=list)
    teacher_steps: int = 0
    steps: int = 0

    def observation(self, scan: np.ndarray, qpos: np.ndarray, qvel: np.ndarray, step: int):
        """The C engine's observation of this world in the batch's state."""
        mirror = self.mirror
        mirror.step = int(step)
        mirror.sim.data.qpos[:3] = qpos[:3]
        mirror.sim.data.qvel[:3] = qvel[:3]
        mirror.place_obstacles()
        return mirror.observe_scan(scan.astype(np.float64))

    def data(self, outcome: str, feature_size: int) -> EpisodeData:
        self.teacher.finish(outcome)
        n = len(self.xs)
        return EpisodeData(
            k=self.k,
            difficulty=self.drawn.difficulty,
            fingerprint=self.drawn.fingerprint,
            outcome=outcome,
            steps=self.steps,
            teacher_share=self.teacher_steps / max(1, self.steps),
            features=np.stack(self.xs) if n else np.zeros((0, feature_size), np.float16),
            labels=np.stack(self.ys).astype(np.float32) if n else np.zeros((0, 2), np.float32),
        )


def collect_on_warp(
    cfg, ks, *, beta: float, actor: StudentActor | None, device: str, num_envs: int
) -> list[EpisodeData]:
    """The labelled training episodes of worlds `ks` of the split (`dagger_rollout.episode`'s,
    with the teacher driving with probability beta and labelling every state), stepped on
    `device` by at most `num_envs` environments; in the order of ks."""
    from dynabarn.learn.warp_env import WarpVectorEnv  # the `gpu` extra

    ks = list(ks)
    probe = DynaBARNEnv(
        split="train", split_seed=cfg.seed, split_profile_sets=tuple(cfg.profile_sets), protocol=cfg.protocol
    )
    try:
        probe.procedural.keep = len(ks)  # every world's file kept until the batch is made
        drawn = [probe.procedural.world(k) for k in ks]
        n = min(num_envs, len(ks))
        env = WarpVectorEnv([str(d.path) for d in drawn], n, device=device, protocol=cfg.protocol)
        templates = [shared_world(str(d.path))[0] for d in drawn]  # the mirrors' models, while the files exist
    finally:
        probe.close()
    rngs = [np.random.default_rng(np.random.SeedSequence([cfg.seed, k, 0])) for k in ks]
    trials = [int(r.integers(2**31)) for r in rngs]
    # Environment w plays episodes w, w + n, w + 2n, ...; a finished environment repeats its
    # last one, unrecorded, until the others are done.
    queues = [list(range(w, len(ks), n)) for w in range(n)]
    width = max(len(q) for q in queues) + 1
    table = np.array([[q[min(j, len(q) - 1)] for j in range(width)] for q in queues])
    env.schedule(np.array(trials)[table], table)
    obs, _ = env.reset()
    protocol, size = get_protocol(cfg.protocol), cfg.features().size()

    def start(w: int, j: int) -> _Running | None:
        if j >= len(queues[w]):
            return None
        i = queues[w][j]
        mirror = Episode(templates[i].fork(), protocol, seed=trials[i], privileged=True)
        features, teacher = Features(cfg.features()), get_planner(cfg.teacher)
        features.reset(mirror.info)
        teacher.reset(mirror.info)
        return _Running(ks[i], drawn[i], mirror, features, teacher, rngs[i])

    played = [0] * n
    running = [start(w, 0) for w in range(n)]
    results: dict[int, EpisodeData] = {}
    worlds = env.worlds
    while any(r is not None for r in running):
        scans, qpos, qvel = obs[:, :720].cpu().numpy(), worlds.d.qpos.numpy(), worlds.d.qvel.numpy()
        steps = worlds.steps.numpy()
        xs = np.zeros((n, size), dtype=np.float32)
        teacher = np.zeros((n, 2), dtype=np.float32)
        for w, r in enumerate(running):
            if r is not None:
                o = r.observation(scans[w], qpos[w], qvel[w], steps[w])
                xs[w] = r.features(o)
                teacher[w] = command_to_action(*r.teacher.act(o))
        actions = teacher.copy()
        if actor is not None:
            with torch.no_grad():
                student = actor.act(torch.from_numpy(xs).to(next(actor.parameters()).device)).cpu().numpy()
        for w, r in enumerate(running):
            if r is None:
                continue
            if actor is None or r.rng.random() < beta:
                r.teacher_steps += 1
            else:
                actions[w] = student[w]
            r.xs.append(xs[w].astype(np.float16))
            r.ys.append(teacher[w])
            r.steps += 1
        obs, _, terminated, truncated, info = env.step(torch.from_numpy(actions).to(obs.device))
        ended = (terminated | truncated).cpu().numpy()
        success = info["success"].cpu().numpy()
        cut = np.zeros(n, dtype=bool)
        for w, r in enumerate(running):
            if r is None:
                continue
            if ended[w]:
                outcome = "success" if success[w] else ("collision" if terminated[w] else "timeout")
            elif len(r.xs) >= cfg.max_steps:
                outcome, cut[w] = "cut", True
            else:
                continue
            results[r.k] = r.data(outcome, size)
            played[w] += 1
            running[w] = start(w, played[w])
        if cut.any():
            env.cut(cut)  # their rows of `obs` (a view on the batch's buffer) now start their next episodes
    return [results[k] for k in ks]
