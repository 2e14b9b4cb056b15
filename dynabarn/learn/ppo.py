"""PPO on the Warp backend (`dynabarn-train ppo --env-backend warp`): thousands of episodes
of a batch of worlds stepped on the device (`learn.warp_env`), the policy and its update in
PyTorch on the same device, no copy through the host in the loop.

The policy is the Fig. 4 actor (`models.Actor`, its tanh mean) with a learned standard
deviation per action, the value a 722-256-256-1 network; the update is PPO's clipped
objective (Schulman et al. 2017) over generalised advantage estimates (gamma, lambda),
minibatches over a few epochs, the gradient's norm clipped. A truncated episode (the
protocol's time limit) is bootstrapped from its final observation's value, a terminated
one (success, collision) is not. The actor is saved as a policy file of kind `ppo`
(`dynabarn-run --planner ppo --planner-config policy=FILE`, evaluated on the C engine),
with a checkpoint after every iteration from which `resume` goes on.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.files import write_atomically
from dynabarn.learn.configs import PPOConfig


def _networks(cfg: PPOConfig, device: str):
    import torch
    from torch import nn

    from dynabarn.planners.learned.models import OBS_DIM, Actor, ObsScale

    torch.manual_seed(cfg.seed)
    actor = Actor(cfg.lookahead).to(device)
    value = nn.Sequential(
        ObsScale(cfg.lookahead), nn.Linear(OBS_DIM, 256), nn.Tanh(), nn.Linear(256, 256), nn.Tanh(), nn.Linear(256, 1)
    ).to(device)
    log_std = nn.Parameter(torch.full((2,), cfg.init_log_std, device=device))
    optimiser = torch.optim.Adam([*actor.parameters(), *value.parameters(), log_std], lr=cfg.lr)
    return actor, value, log_std, optimiser


def _advantages(cfg: PPOConfig, rewards, values, next_values, terminal, ended):
    """GAE over a rollout (T, N): `next_values` the value after each period (the final
    observation's where an episode ended; zeroed where it terminated), `ended` where the
    next period belongs to another episode."""
    import torch

    advantages = torch.zeros_like(rewards)
    running = torch.zeros_like(rewards[0])
    for t in reversed(range(rewards.shape[0])):
        delta = rewards[t] + cfg.gamma * next_values[t] * (~terminal[t]) - values[t]
        running = delta + cfg.gamma * cfg.gae_lambda * running * (~ended[t])
        advantages[t] = running
    return advantages


def _collect(cfg: PPOConfig, env, obs, actor, value, log_std):
    """One rollout of every world: the tensors PPO's update takes, and the next observation."""
    import torch

    T = cfg.rollout
    keys = ("obs", "actions", "logp", "values", "rewards", "next_values", "terminal", "ended", "success")
    store = {k: [] for k in keys}
    with torch.no_grad():
        for _ in range(T):
            dist = torch.distributions.Normal(actor(obs), log_std.exp())
            action = dist.sample()
            next_obs, reward, terminated, truncated, info = env.step(action.clamp(-1.0, 1.0))
            ended = terminated | truncated
            after = torch.where(ended[:, None], info["final_observation"], next_obs)
            store["obs"].append(obs)
            store["actions"].append(action)
            store["logp"].append(dist.log_prob(action).sum(-1))
            store["values"].append(value(obs).squeeze(-1))
            store["rewards"].append(reward.clone())  # the environment's buffer: the next step rewrites it
            store["next_values"].append(value(after).squeeze(-1))
            store["terminal"].append(terminated)
            store["ended"].append(ended)
            store["success"].append(info["success"])
            obs = next_obs.clone()
    batch = {k: torch.stack(v) for k, v in store.items()}
    # Counted once per rollout, not per period: each read waits for the device.
    seen = {"episodes": int(batch["ended"].sum()), "successes": int(batch.pop("success").sum())}
    return batch, obs, {**seen, "reward": float(batch["rewards"].mean()) * T}


def _update(cfg: PPOConfig, batch, advantages, actor, value, log_std, optimiser) -> dict:
    import torch

    returns = advantages + batch["values"]
    flat = {k: v.reshape(-1, *v.shape[2:]) for k, v in batch.items()}
    adv, ret = advantages.reshape(-1), returns.reshape(-1)
    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    n = adv.shape[0]
    size = n // cfg.minibatches
    for _ in range(cfg.epochs):
        order = torch.randperm(n, device=adv.device)
        for m in range(cfg.minibatches):
            idx = order[m * size : (m + 1) * size]
            dist = torch.distributions.Normal(actor(flat["obs"][idx]), log_std.exp())
            ratio = (dist.log_prob(flat["actions"][idx]).sum(-1) - flat["logp"][idx]).exp()
            policy_loss = -torch.min(ratio * adv[idx], ratio.clamp(1 - cfg.clip, 1 + cfg.clip) * adv[idx]).mean()
            value_loss = (value(flat["obs"][idx]).squeeze(-1) - ret[idx]).pow(2).mean()
            loss = policy_loss + cfg.value_coef * value_loss - cfg.entropy_coef * dist.entropy().sum(-1).mean()
            optimiser.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_([*actor.parameters(), *value.parameters(), log_std], cfg.max_grad_norm)
            optimiser.step()
    # The last minibatch's losses, read once (a read per minibatch would wait for the device each time).
    return {"policy_loss": float(policy_loss), "value_loss": float(value_loss)}


def train_ppo(
    worlds: str | list[str] | dict,
    out: Path,
    cfg: PPOConfig,
    *,
    device: str = "cpu",
    resume: bool = True,
    progress: Callable[..., object] | None = None,
) -> dict:
    """Train into `out` (policy.pt, checkpoint.pt, history.json) on `worlds`: a world file,
    a list of them, or `DynaBARNVectorEnv`'s keywords choosing them (`{"world_set": ...,
    "difficulty": ...}`, `{"split": "train", ...}`); a run whose checkpoint is there goes on
    from it. Returns the history."""

    from dynabarn.learn.vector_env import warp_vector_env
    from dynabarn.learn.warp_env import WarpVectorEnv
    from dynabarn.planners.learned.models import save_policy

    if isinstance(worlds, dict):
        env = warp_vector_env(cfg.num_envs, device=device, lookahead=cfg.lookahead, seed=cfg.seed, **worlds)
    else:
        env = WarpVectorEnv(worlds, cfg.num_envs, device=device, lookahead=cfg.lookahead, seed=cfg.seed)
    out.mkdir(parents=True, exist_ok=True)  # after the worlds are accepted: a refusal leaves nothing behind
    torch_device = "cpu" if device == "cpu" else device
    actor, value, log_std, optimiser = _networks(cfg, torch_device)
    history, checkpoint = [], out / "checkpoint.pt"
    if resume and checkpoint.is_file():
        history = _resume(out, actor, value, log_std, optimiser)
    obs, _ = env.reset(seed=cfg.seed + len(history))  # a resumed run draws trials anew
    bar = progress(total=cfg.iterations, initial=len(history)) if progress else None
    for iteration in range(len(history), cfg.iterations):
        t0 = time.perf_counter()
        batch, obs, seen = _collect(cfg, env, obs, actor, value, log_std)
        advantages = _advantages(
            cfg, batch["rewards"], batch["values"], batch["next_values"], batch["terminal"], batch["ended"]
        )
        losses = _update(cfg, batch, advantages, actor, value, log_std, optimiser)
        history.append(
            {
                "iteration": iteration + 1,
                "steps": (iteration + 1) * cfg.num_envs * cfg.rollout,
                **seen,
                **losses,
                "log_std": [round(float(v), 4) for v in log_std.detach().cpu()],
                "seconds": round(time.perf_counter() - t0, 3),
            }
        )
        _save(out, actor, value, log_std, optimiser, history, cfg, save_policy)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return {"history": history, "policy": str(out / "policy.pt")}


CHECKPOINT = "dynabarn-ppo-checkpoint"
"""The format name a PPO checkpoint carries."""


def _resume(out: Path, actor, value, log_std, optimiser) -> list[dict]:
    """The run in `out` where its last iteration left it: the networks, the optimiser and
    the history, checked; one line when the folder holds something else."""
    from dynabarn.planners.learned.models import load_tensors

    try:
        state = load_tensors(out / "checkpoint.pt")
        if not isinstance(state, dict) or state.get("format") != CHECKPOINT:
            raise ValueError("not a PPO checkpoint")
        actor.load_state_dict(state["actor"])
        value.load_state_dict(state["value"])
        log_std.data.copy_(state["log_std"])
        optimiser.load_state_dict(state["optimiser"])
        history = json.loads((out / "history.json").read_text())
        if not isinstance(history, list) or len(history) != int(state["iterations"]):
            raise ValueError("history.json does not match the checkpoint")
    except Exception as exc:  # PyTorch's and JSON's refusals run to a page: their first line says it
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:160]
        raise DynabarnError(
            f"{out / 'checkpoint.pt'}: cannot resume ({type(exc).__name__}: {first}); remove the folder to start anew"
        ) from None
    return history


def _save(out: Path, actor, value, log_std, optimiser, history, cfg: PPOConfig, save_policy) -> None:
    """The policy, the checkpoint and the history, each written whole (temporary file,
    fsync, rename): a run stopped at any moment resumes from its last iteration."""
    from dynabarn.planners.learned.models import save_tensors

    notes = {**cfg.notes, "config": {k: v for k, v in asdict(cfg).items() if k != "notes"}, "iterations": len(history)}
    cpu_actor = type(actor)(cfg.lookahead)
    cpu_actor.load_state_dict({k: v.detach().cpu() for k, v in actor.state_dict().items()})
    save_policy(cpu_actor, out / "policy.pt", kind="ppo", lookahead=cfg.lookahead, notes=notes)
    state = {"actor": actor.state_dict(), "value": value.state_dict(), "log_std": log_std.detach()}
    state |= {"format": CHECKPOINT, "iterations": len(history), "optimiser": optimiser.state_dict()}
    save_tensors(out / "checkpoint.pt", state)
    write_atomically(out / "history.json", json.dumps(history, indent=1) + "\n")
