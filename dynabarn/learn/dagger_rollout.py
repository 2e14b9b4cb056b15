"""DAgger's episodes: the mixed policy drives, the privileged teacher labels every state.

Runs in worker processes (`run_episodes` hands them jobs of a few episodes, results in
the order asked): each keeps its `DynaBARN-v0` environment and teacher between jobs.
Everything an episode does follows from (config, split, world k, weights, beta): the
trial seed and the coin that picks who drives are drawn from `SeedSequence([seed, k])`.
"""

from __future__ import annotations

import atexit
from dataclasses import dataclass

import numpy as np
import torch

from dynabarn.learn.expert import EXPERT_ACTION, ExpertLabels
from dynabarn.planners.learned.features import Features
from dynabarn.planners.learned.student import StudentActor, student_for

JOB_EPISODES = 4
"""Episodes per job: small enough to balance two workers, large enough to keep them busy."""
_WORKER: dict = {}


@dataclass
class EpisodeData:
    k: int
    difficulty: str
    fingerprint: str
    outcome: str
    steps: int
    teacher_share: float
    features: np.ndarray  # (steps, n) float16; empty when not labelled
    labels: np.ndarray  # (steps, 2) the teacher's normalised actions


def _env(cfg, split: str):
    from dynabarn.learn.env import DynaBARNEnv

    key = (split, cfg.seed, tuple(cfg.profile_sets), cfg.protocol)
    if _WORKER.get("key") != key:
        _close_env()
        torch.set_num_threads(1)
        _WORKER["env"] = DynaBARNEnv(
            split=split, split_seed=cfg.seed, split_profile_sets=tuple(cfg.profile_sets), protocol=cfg.protocol
        )
        _WORKER["key"] = key
    return _WORKER["env"]


def _close_env() -> None:
    env = _WORKER.pop("env", None)
    _WORKER.pop("key", None)
    if env is not None:
        env.close()


# The split's world files live in a temporary folder the environment removes on close; a
# pool's worker ends through sys.exit, which runs this. One entry for whichever environment
# is current: an entry per environment would keep every closed one (and its worlds) alive.
atexit.register(_close_env)


def episode_draws(cfg, split: str, k: int) -> tuple[int, np.random.Generator]:
    """Episode k's trial seed, and the generator that then tosses its coin step by step:
    everything an episode draws, from `SeedSequence([seed, k, split])` (both collections')."""
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, k, 0 if split == "train" else 1]))
    return int(rng.integers(2**31)), rng


def episode(cfg, split: str, k: int, beta: float, actor: StudentActor | None, label: bool) -> EpisodeData:
    """One episode of world k of `split`: who drives is drawn per step (teacher with
    probability beta). The teacher acts through the environment's step (`ExpertLabels`):
    the student's and the teacher's episodes differ only in the action passed to it."""
    env = _env(cfg, split)
    labelled = ExpertLabels(env, cfg.teacher) if label else env
    trial, rng = episode_draws(cfg, split, k)
    _, info = labelled.reset(options={"world_index": k, "trial_seed": trial, "privileged": label})
    features = Features(cfg.features())
    features.reset(env.episode.info)
    xs, ys, teacher_steps, steps = [], [], 0, 0
    outcome = "error"
    step_info = info
    while True:
        x = features(env.observation)
        a_teacher = step_info.get(EXPERT_ACTION)
        if actor is None or (a_teacher is not None and rng.random() < beta):
            action, teacher_steps = a_teacher, teacher_steps + 1
        else:
            with torch.no_grad():
                action = actor.act(torch.from_numpy(x[None]).float()).numpy()[0]
        if label:
            xs.append(x.astype(np.float16))
            ys.append(a_teacher)
        _, _, terminated, truncated, step_info = labelled.step(action)
        steps += 1
        if terminated or truncated:
            outcome = step_info["outcome"] or "error"
            break
        if label and len(xs) >= cfg.max_steps:
            outcome = "cut"
            labelled.stop(outcome)
            break
    n = len(xs)
    return EpisodeData(
        k=k,
        difficulty=info["difficulty"],
        fingerprint=info["fingerprint"],
        outcome=outcome,
        steps=steps,
        teacher_share=teacher_steps / max(1, steps),
        features=np.stack(xs) if n else np.zeros((0, cfg.features().size()), np.float16),
        labels=np.stack(ys).astype(np.float32) if n else np.zeros((0, 2), np.float32),
    )


def student_from(cfg, weights: dict | None) -> StudentActor | None:
    """The student of `weights` (CPU tensors), ready to act (None: no student yet)."""
    if weights is None:
        return None
    classes = weights.get("classes")
    actor = student_for(cfg.features(), None if classes is None else classes.numpy(), cfg.encoder)
    actor.load_state_dict(weights)
    return actor.eval()


def _job(cfg, split: str, ks: list[int], beta: float, weights: dict | None, label: bool) -> list[EpisodeData]:
    actor = student_from(cfg, weights)
    return [episode(cfg, split, k, beta, actor, label) for k in ks]


def run_episodes(pool, cfg, split: str, ks, *, beta: float, weights: dict | None, label: bool) -> list[EpisodeData]:
    """Episodes of worlds `ks` of `split`, spread over the pool's workers, in the order of ks."""
    ks = list(ks)
    chunks = [ks[i : i + JOB_EPISODES] for i in range(0, len(ks), JOB_EPISODES)]
    futures = [pool.submit(_job, cfg, split, c, beta, weights, label) for c in chunks]
    return [e for f in futures for e in f.result()]
