"""TD3 (Fujimoto et al. 2018) with the Fig. 4 actor and critics, on `DynaBARN-v0`.

Twin critics, target policy smoothing (noise 0.2 clipped at 0.5), delayed actor updates
(every 2 critic updates), soft target updates (tau 0.005), Gaussian exploration noise
(0.1), uniform random actions for the first `start_steps`. Experience comes from K
environments stepped together (`gymnasium.vector`, one process each with `--envs K > 1`).
Every `eval_every` steps the deterministic actor is evaluated on fixed (world, seed) pairs
and a checkpoint is written; at the end, a learning-curve PNG.
"""

from __future__ import annotations

import copy
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import gymnasium
import numpy as np
import torch

from dynabarn.files import save_atomically, write_atomically
from dynabarn.learn import ENV_ID
from dynabarn.planners.learned.models import Actor, Critic, save_policy


@dataclass
class TD3Config:
    steps: int = 20_000
    envs: int = 1
    world_set: str = "paper60"
    difficulty: str | None = "easy"
    protocol: str = "barn"
    lookahead: float = 2.0
    gamma: float = 0.99
    tau: float = 0.005
    lr: float = 3e-4
    batch_size: int = 256
    buffer_size: int = 200_000
    start_steps: int = 2_000
    exploration_noise: float = 0.1
    policy_noise: float = 0.2
    noise_clip: float = 0.5
    policy_delay: int = 2
    eval_every: int = 5_000
    eval_episodes: int = 10
    seed: int = 0


@dataclass
class TD3Report:
    steps: int
    seconds: float
    evaluations: list[dict] = field(default_factory=list)
    episodes: int = 0


def _make_env(cfg: TD3Config):
    def thunk():
        return gymnasium.make(
            ENV_ID, world_set=cfg.world_set, difficulty=cfg.difficulty, protocol=cfg.protocol, lookahead=cfg.lookahead
        )

    return thunk


def evaluate(actor: Actor, cfg: TD3Config, n: int) -> dict:
    """Success rate and mean return of the deterministic actor on fixed (world, seed) pairs."""
    env = _make_env(cfg)()
    successes, returns = 0, []
    for k in range(n):
        obs, _ = env.reset(seed=cfg.seed + 10_000 + k, options={"world_index": k, "trial_seed": k})
        done, total = False, 0.0
        while not done:
            with torch.no_grad():
                a = actor(torch.as_tensor(obs[None])).numpy()[0]
            obs, r, term, trunc, info = env.step(a)
            total += r
            done = term or trunc
        successes += info["outcome"] == "success"
        returns.append(total)
    env.close()
    return {"success": successes / n, "return": float(np.mean(returns))}


# Over 80 lines on purpose: the TD3 loop (Fujimoto et al. 2018, Alg. 1) in one piece, as
# the algorithm box reads; the networks, buffer and plots live outside it.
def train_td3(cfg: TD3Config, out_dir: Path, *, progress=None) -> TD3Report:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    vec_cls = gymnasium.vector.AsyncVectorEnv if cfg.envs > 1 else gymnasium.vector.SyncVectorEnv
    envs = vec_cls([_make_env(cfg) for _ in range(cfg.envs)])
    obs_dim, act_dim = 722, 2
    actor = Actor(cfg.lookahead)
    critic1, critic2 = Critic(cfg.lookahead), Critic(cfg.lookahead)
    actor_t, critic1_t, critic2_t = copy.deepcopy(actor), copy.deepcopy(critic1), copy.deepcopy(critic2)
    actor_opt = torch.optim.Adam(actor.parameters(), lr=cfg.lr)
    critic_opt = torch.optim.Adam([*critic1.parameters(), *critic2.parameters()], lr=cfg.lr)

    size = cfg.buffer_size
    buf_o = np.zeros((size, obs_dim), np.float32)
    buf_a = np.zeros((size, act_dim), np.float32)
    buf_r = np.zeros(size, np.float32)
    buf_o2 = np.zeros((size, obs_dim), np.float32)
    buf_d = np.zeros(size, np.float32)
    ptr, full = 0, False

    report = TD3Report(steps=cfg.steps, seconds=0.0)
    obs, _ = envs.reset(seed=cfg.seed)
    t0 = time.perf_counter()
    n_updates = 0
    step = 0
    bar = progress(total=cfg.steps) if progress else None
    while step < cfg.steps:
        if step < cfg.start_steps:
            act = rng.uniform(-1, 1, (cfg.envs, act_dim)).astype(np.float32)
        else:
            with torch.no_grad():
                act = actor(torch.as_tensor(obs)).numpy()
            act = np.clip(act + rng.normal(0, cfg.exploration_noise, act.shape), -1, 1).astype(np.float32)
        obs2, rew, term, trunc, _ = envs.step(act)
        # With autoreset, the row after a done holds the new episode's first observation;
        # the true last observation of a finished episode is not needed for terminal
        # transitions (no bootstrap) and is approximated for truncated ones.
        for i in range(cfg.envs):
            buf_o[ptr], buf_a[ptr], buf_r[ptr] = obs[i], act[i], rew[i]
            buf_o2[ptr], buf_d[ptr] = obs2[i], float(term[i])
            ptr = (ptr + 1) % size
            full = full or ptr == 0
            report.episodes += bool(term[i] or trunc[i])
        obs = obs2
        step += cfg.envs
        if bar:
            bar.update(cfg.envs)
        n = size if full else ptr
        if step >= cfg.start_steps and n >= cfg.batch_size:
            for _ in range(cfg.envs):
                idx = rng.integers(0, n, cfg.batch_size)
                o, a = torch.as_tensor(buf_o[idx]), torch.as_tensor(buf_a[idx])
                r, o2, d = torch.as_tensor(buf_r[idx]), torch.as_tensor(buf_o2[idx]), torch.as_tensor(buf_d[idx])
                with torch.no_grad():
                    noise = (torch.randn_like(a) * cfg.policy_noise).clamp(-cfg.noise_clip, cfg.noise_clip)
                    a2 = (actor_t(o2) + noise).clamp(-1, 1)
                    q_t = torch.min(critic1_t(o2, a2), critic2_t(o2, a2)).squeeze(-1)
                    y = r + cfg.gamma * (1 - d) * q_t
                loss_c = ((critic1(o, a).squeeze(-1) - y) ** 2).mean() + ((critic2(o, a).squeeze(-1) - y) ** 2).mean()
                critic_opt.zero_grad()
                loss_c.backward()
                critic_opt.step()
                n_updates += 1
                if n_updates % cfg.policy_delay == 0:
                    loss_a = -critic1(o, actor(o)).mean()
                    actor_opt.zero_grad()
                    loss_a.backward()
                    actor_opt.step()
                    with torch.no_grad():
                        for net, tgt in ((actor, actor_t), (critic1, critic1_t), (critic2, critic2_t)):
                            for p, pt in zip(net.parameters(), tgt.parameters(), strict=True):
                                pt.mul_(1 - cfg.tau).add_(cfg.tau * p)
        if step % cfg.eval_every < cfg.envs or step >= cfg.steps:
            ev = evaluate(actor, cfg, cfg.eval_episodes)
            ev["step"] = step
            ev["seconds"] = time.perf_counter() - t0
            report.evaluations.append(ev)
            save_policy(
                actor,
                out_dir / f"checkpoint_{step:08d}.pt",
                kind="td3",
                lookahead=cfg.lookahead,
                notes={"step": step, **ev},
            )
    envs.close()
    if bar:
        bar.close()
    report.seconds = time.perf_counter() - t0
    save_policy(
        actor,
        out_dir / "policy.pt",
        kind="td3",
        lookahead=cfg.lookahead,
        notes={"steps": step, "config": asdict(cfg), "final_eval": report.evaluations[-1]},
    )
    write_atomically(out_dir / "training.json", json.dumps({"config": asdict(cfg), **asdict(report)}, indent=1))
    plot_learning_curve(report, out_dir / "learning_curve.png")
    return report


def plot_learning_curve(report: TD3Report, path: Path) -> Path:
    # A Figure of its own, not pyplot: no global backend switch, no figure registry.
    from matplotlib.figure import Figure

    steps = [e["step"] for e in report.evaluations]
    fig = Figure(figsize=(6, 3.5), dpi=120)
    ax = fig.subplots()
    ax.plot(steps, [e["success"] for e in report.evaluations], "o-", label="success rate")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("success rate")
    ax.set_ylim(-0.02, 1.02)
    ax2 = ax.twinx()
    ax2.plot(steps, [e["return"] for e in report.evaluations], "s--", color="tab:orange", label="mean return")
    ax2.set_ylabel("mean return")
    ax.grid(alpha=0.3)
    ax.set_title("TD3 on DynaBARN-v0 (deterministic evaluation)", fontsize=10)
    fig.tight_layout()
    save_atomically(path, lambda f: fig.savefig(f, format="png"))
    return path
