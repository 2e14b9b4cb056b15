"""TD3 (Fujimoto et al. 2018) with the Fig. 4 actor and critics, on `DynaBARN-v0`.

The algorithm: twin critics, target policy smoothing (noise 0.2 clipped at 0.5), delayed
actor updates (every 2 critic updates), soft target updates (tau 0.005), Gaussian
exploration noise. Experience comes from K environments stepped together
(`gymnasium.vector`, same-step autoreset, so a finished episode's true last observation is
stored and a time-limit truncation bootstraps from it).

Departures from the paper's plain TD3, each switchable (`TD3Config`), because a CPU has
about 10^5 updates where the paper had 2 x 10^7 steps per difficulty:
- `demos`: episodes of the privileged oracle in the training worlds, with the
  environment's rewards, kept in a demonstration buffer that fills `demo_share` of every
  batch (DDPGfD-style, Vecerik et al. 2017);
- `bc_epochs`: the actor starts as behaviour cloning of those demonstrations,
  `critic_warmup` critic-only updates on them come first, and the actor is left alone
  for the first `actor_start` steps, while the critic learns the cloned policy's values
  from its own experience (collisions included: the demonstrations have none);
- `bc_weight`: the actor's loss adds that much of the squared distance to the
  demonstrated actions (TD3+BC, Fujimoto and Gu 2021, with Q normalised by its mean
  magnitude), decaying linearly to 0 at `bc_decay_steps`;
- `update_every`: one gradient update per that many environment steps.

Every `eval_every` steps the deterministic actor is evaluated on fixed (world, seed) pairs
of the training worlds with seeds of their own (EVAL_SEED_BASE + k, never the
benchmark's 0..9), and the whole state (networks, optimisers, buffers, generators) is
checkpointed, so `train_td3` resumes an interrupted run from its last checkpoint. The run
writes `train.log`, `training.json`, `learning_curve.png` and `policy.pt`.
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

from dynabarn.errors import DynabarnError
from dynabarn.files import save_atomically, write_atomically
from dynabarn.learn import ENV_ID
from dynabarn.learn.bc import fit_actor
from dynabarn.learn.configs import TD3Config, resuming, saved_config
from dynabarn.learn.replay_buffer import ReplayBuffer, collect_demonstrations
from dynabarn.planners.learned.models import Actor, Critic, load_tensors, save_policy, save_tensors

EVAL_SEED_BASE = 2_000_000
"""Trial seeds of the evaluations during training (the benchmark uses 0..trials-1)."""
STATE, REPLAY, DEMOS, LOG = "state.pt", "replay.npz", "demos.npz", "train.log"


@dataclass
class TD3Report:
    steps: int
    seconds: float
    evaluations: list[dict] = field(default_factory=list)
    episodes: int = 0
    demo_outcomes: dict = field(default_factory=dict)
    updates: int = 0


def _make_env(cfg: TD3Config):
    def thunk():
        return gymnasium.make(ENV_ID, **cfg.env_kwargs())

    return thunk


def evaluate(actor: Actor, cfg: TD3Config, n: int) -> dict:
    """Success rate and mean return of the deterministic actor on fixed (world, seed) pairs."""
    env = _make_env(cfg)()
    worlds = len(env.unwrapped.entries)
    successes, collisions, returns = 0, 0, []
    for k in range(n):
        seed = EVAL_SEED_BASE + k
        # Spread over the worlds (and so over the difficulties, which come in blocks).
        obs, _ = env.reset(
            seed=seed, options={"world_index": (k * worlds) // n if n < worlds else k, "trial_seed": seed}
        )
        done, total = False, 0.0
        while not done:
            with torch.no_grad():
                a = actor(torch.as_tensor(obs[None])).numpy()[0]
            obs, r, term, trunc, info = env.step(a)
            total += r
            done = term or trunc
        successes += info["outcome"] == "success"
        collisions += info["outcome"] == "collision"
        returns.append(total)
    env.close()
    return {"success": successes / n, "collision": collisions / n, "return": float(np.mean(returns))}


class Learner:
    """The networks, their optimisers and one TD3 gradient update."""

    def __init__(self, cfg: TD3Config) -> None:
        self.cfg = cfg
        self.actor = Actor(cfg.lookahead)
        self.critic1, self.critic2 = Critic(cfg.lookahead), Critic(cfg.lookahead)
        self.actor_t = copy.deepcopy(self.actor)
        self.critic1_t, self.critic2_t = copy.deepcopy(self.critic1), copy.deepcopy(self.critic2)
        self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=cfg.lr)
        self.clone_opt = torch.optim.Adam(self.actor.parameters(), lr=cfg.bc_lr)
        self.critic_opt = torch.optim.Adam([*self.critic1.parameters(), *self.critic2.parameters()], lr=cfg.lr)
        self.updates = 0

    def modules(self) -> dict[str, torch.nn.Module | torch.optim.Optimizer]:
        return {
            "actor": self.actor,
            "critic1": self.critic1,
            "critic2": self.critic2,
            "actor_t": self.actor_t,
            "critic1_t": self.critic1_t,
            "critic2_t": self.critic2_t,
            "actor_opt": self.actor_opt,
            "critic_opt": self.critic_opt,
        }

    def clone_demonstrations(self, demos: ReplayBuffer, epochs: int, gen: np.random.Generator) -> float:
        """Behaviour cloning of the demonstrated actions; the targets follow. Returns the
        last epoch's mean loss."""
        losses = fit_actor(
            self.actor,
            self.clone_opt,
            torch.as_tensor(demos.obs[: len(demos)].astype(np.float32)),
            torch.as_tensor(demos.act[: len(demos)]),
            epochs=range(epochs),
            batch_size=self.cfg.batch_size,
            permutation=gen.permutation,
        )
        self.actor_t.load_state_dict(self.actor.state_dict())
        return losses[-1] if losses else float("nan")

    def update(self, batch, n_demo: int, bc_weight: float, *, actor_too: bool = True) -> None:
        cfg = self.cfg
        o, a = torch.as_tensor(batch.obs), torch.as_tensor(batch.act)
        r, o2, d = torch.as_tensor(batch.rew), torch.as_tensor(batch.next_obs), torch.as_tensor(batch.done)
        with torch.no_grad():
            noise = (torch.randn_like(a) * cfg.policy_noise).clamp(-cfg.noise_clip, cfg.noise_clip)
            a2 = (self.actor_t(o2) + noise).clamp(-1, 1)
            q_t = torch.min(self.critic1_t(o2, a2), self.critic2_t(o2, a2)).squeeze(-1)
            y = r + cfg.gamma * (1 - d) * q_t
        loss_c = ((self.critic1(o, a).squeeze(-1) - y) ** 2).mean() + ((self.critic2(o, a).squeeze(-1) - y) ** 2).mean()
        self.critic_opt.zero_grad()
        loss_c.backward()
        self.critic_opt.step()
        self.updates += 1
        if self.updates % cfg.policy_delay:
            return
        if actor_too:
            pi = self.actor(o)
            q = self.critic1(o, pi)
            loss_a = -q.mean() / q.abs().mean().detach().clamp_min(1e-6)
            if bc_weight > 0 and n_demo:
                loss_a = loss_a + bc_weight * ((pi[:n_demo] - a[:n_demo]) ** 2).mean()
            self.actor_opt.zero_grad()
            loss_a.backward()
            self.actor_opt.step()
        with torch.no_grad():
            for net, tgt in (
                (self.actor, self.actor_t),
                (self.critic1, self.critic1_t),
                (self.critic2, self.critic2_t),
            ):
                torch._foreach_lerp_(list(tgt.parameters()), list(net.parameters()), cfg.tau)


def _joined(demo, online, rng, cfg: TD3Config):
    """A batch with the demonstrations first (`demo_share` of it) and online experience after."""
    n_demo = round(cfg.batch_size * cfg.demo_share) if len(demo) else 0
    if len(online) == 0:
        return demo.sample(rng, cfg.batch_size), cfg.batch_size
    parts = (
        [demo.sample(rng, n_demo), online.sample(rng, cfg.batch_size - n_demo)]
        if n_demo
        else [online.sample(rng, cfg.batch_size)]
    )
    keys = ("obs", "act", "rew", "next_obs", "done")
    merged = type(parts[0])(*(np.concatenate([getattr(p, k) for p in parts]) for k in keys))
    return merged, n_demo


def _save_state(out: Path, learner: Learner, report: TD3Report, step: int, rng, online: ReplayBuffer) -> None:
    online.save(out / REPLAY)
    state = {name: m.state_dict() for name, m in learner.modules().items()}
    state |= {
        "step": step,
        "updates": learner.updates,
        "report": asdict(report),
        "rng": json.dumps(rng.bit_generator.state),
        "torch_rng": torch.get_rng_state(),
    }
    save_tensors(out / STATE, state)


def _resume(out: Path, learner: Learner, rng) -> tuple[int, TD3Report, ReplayBuffer, ReplayBuffer]:
    """Step, report and buffers of the last checkpoint, its weights and random states set
    (tensors and plain data only: `weights_only`, so a checkpoint never runs code); one line
    if anything in it is damaged."""
    with resuming(out):
        state = load_tensors(out / STATE)
        for name, m in learner.modules().items():
            m.load_state_dict(state[name])
        step, learner.updates = int(state["step"]), int(state["updates"])
        report = TD3Report(**state["report"])
        rng.bit_generator.state = json.loads(state["rng"])
        torch.set_rng_state(state["torch_rng"])
        demos, online = ReplayBuffer.load(out / DEMOS), ReplayBuffer.load(out / REPLAY)
    return step, report, demos, online


def _identity(cfg: dict | None) -> dict | None:
    return None if cfg is None else {k: v for k, v in cfg.items() if k not in ("threads", "steps")}


def _log(out: Path, line: str) -> None:
    with (out / LOG).open("a") as f:
        f.write(line + "\n")


# Over 80 lines on purpose: the TD3 loop (Fujimoto et al. 2018, Alg. 1) in one piece, as
# the algorithm box reads, with its checkpoint and resume around it.
def train_td3(cfg: TD3Config, out_dir: Path, *, progress=None) -> TD3Report:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    learner = Learner(cfg)
    report = TD3Report(steps=cfg.steps, seconds=0.0)
    config_path = out / "config.json"
    step = 0
    if (out / STATE).is_file():  # resume: the same configuration, from the last checkpoint
        old = saved_config(config_path)
        # The thread count may change between sessions (a busier machine), and the step
        # count (to train on, or to stop earlier); nothing else may.
        if _identity(old) != _identity(json.loads(json.dumps(asdict(cfg)))):
            raise DynabarnError(f"{out} holds a run with another configuration ({config_path}); use another --out")
        step, report, demos, online = _resume(out, learner, rng)
        report.steps = cfg.steps
        write_atomically(config_path, json.dumps(asdict(cfg), indent=1))
        _log(out, f"resumed at step {step}")
    else:
        write_atomically(config_path, json.dumps(asdict(cfg), indent=1))
        (out / LOG).unlink(missing_ok=True)
        demos, online = ReplayBuffer(max(1, cfg.demos * 400)), ReplayBuffer(cfg.buffer_size)
        t0 = time.perf_counter()
        if cfg.demos:
            # Demonstrations already collected for this folder (an earlier attempt) are kept.
            wanted = {"episodes": cfg.demos, "env": cfg.env_kwargs()}
            meta = out / (DEMOS + ".json")
            kept = json.loads(meta.read_text()) if (out / DEMOS).is_file() and meta.is_file() else {}
            if kept.get("of") == wanted:
                demos = ReplayBuffer.load(out / DEMOS)
                report.demo_outcomes = kept["outcomes"]
            else:
                report.demo_outcomes = collect_demonstrations(cfg.env_kwargs(), cfg.demos, demos, jobs=cfg.threads)
                demos.save(out / DEMOS)
                write_atomically(meta, json.dumps({"of": wanted, "outcomes": report.demo_outcomes}))
            loss = learner.clone_demonstrations(demos, cfg.bc_epochs, rng)
            for _ in range(cfg.critic_warmup):
                learner.update(demos.sample(rng, cfg.batch_size), 0, 0.0, actor_too=False)
            _log(
                out,
                f"demonstrations {report.demo_outcomes} ({len(demos)} transitions); behaviour cloning loss "
                f"{loss:.4f}; {cfg.critic_warmup} critic updates; {time.perf_counter() - t0:.0f} s",
            )
        report.evaluations.append({"step": 0, "seconds": 0.0, **evaluate(learner.actor, cfg, cfg.eval_episodes)})
        _log(out, json.dumps(report.evaluations[-1]))
    vector_env = gymnasium.vector.AsyncVectorEnv if cfg.envs > 1 else gymnasium.vector.SyncVectorEnv
    envs = vector_env(
        [_make_env(cfg) for _ in range(cfg.envs)], autoreset_mode=gymnasium.vector.AutoresetMode.SAME_STEP
    )
    obs, _ = envs.reset(seed=cfg.seed + step)
    t0 = time.perf_counter() - report.seconds
    recent: list[float] = []
    bar = progress(total=cfg.steps, initial=step) if progress else None
    while step < cfg.steps:
        if step < cfg.start_steps:
            act = rng.uniform(-1, 1, (cfg.envs, 2)).astype(np.float32)
        else:
            with torch.no_grad():
                act = learner.actor(torch.as_tensor(obs)).numpy()
            act = np.clip(act + rng.normal(0, cfg.exploration_noise, act.shape), -1, 1).astype(np.float32)
        obs2, rew, term, trunc, info = envs.step(act)
        for i in range(cfg.envs):
            ended = bool(term[i] or trunc[i])
            # Same-step autoreset: obs2 already starts the next episode; the true last
            # observation is in final_obs (a truncated episode bootstraps from it).
            last = info["final_obs"][i] if ended else obs2[i]
            online.add(obs[i], act[i], rew[i], last, float(term[i]))
            if ended:
                report.episodes += 1
                recent = [*recent[-49:], float(info["final_info"]["is_success"][i])]
        obs = obs2
        step += cfg.envs
        if bar:
            bar.update(cfg.envs)
        if step >= cfg.start_steps and len(online) + len(demos) >= cfg.batch_size:
            bc_weight = cfg.bc_weight * max(0.0, 1.0 - step / max(1, cfg.bc_decay_steps))
            for _ in range(max(1, cfg.envs // cfg.update_every) if step % cfg.update_every < cfg.envs else 0):
                batch, n_demo = _joined(demos, online, rng, cfg)
                learner.update(batch, n_demo, bc_weight, actor_too=step >= cfg.actor_start)
        if step % cfg.eval_every < cfg.envs or step >= cfg.steps:
            report.seconds = time.perf_counter() - t0
            ev = {"step": step, "seconds": report.seconds, **evaluate(learner.actor, cfg, cfg.eval_episodes)}
            ev["train_success_last50"] = float(np.mean(recent)) if recent else None
            report.evaluations.append(ev)
            report.updates = learner.updates
            _log(out, json.dumps(ev))
            save_policy(learner.actor, out / f"checkpoint_{step:08d}.pt", kind="td3", lookahead=cfg.lookahead, notes=ev)
            _save_state(out, learner, report, step, rng, online)
    envs.close()
    if bar:
        bar.close()
    report.seconds = time.perf_counter() - t0
    report.updates = learner.updates
    notes = {"steps": step, "config": asdict(cfg), "final_eval": report.evaluations[-1]}
    save_policy(learner.actor, out / "policy.pt", kind="td3", lookahead=cfg.lookahead, notes=notes)
    write_atomically(out / "training.json", json.dumps({"config": asdict(cfg), **asdict(report)}, indent=1))
    plot_learning_curve(report, out / "learning_curve.png")
    return report


def plot_learning_curve(report: TD3Report, path: Path) -> Path:
    # A Figure of its own, not pyplot: no global backend switch, no figure registry.
    from matplotlib.figure import Figure

    steps = [e["step"] for e in report.evaluations]
    fig = Figure(figsize=(6, 3.5), dpi=120)
    ax = fig.subplots()
    ax.plot(steps, [e["success"] for e in report.evaluations], "o-", label="success rate")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("success rate (evaluation seeds)")
    ax.set_ylim(-0.02, 1.02)
    ax2 = ax.twinx()
    ax2.plot(steps, [e["return"] for e in report.evaluations], "s--", color="tab:orange", label="mean return")
    ax2.set_ylabel("mean return")
    ax.grid(alpha=0.3)
    ax.set_title("TD3 on DynaBARN-v0 (deterministic evaluation)", fontsize=10)
    fig.tight_layout()
    save_atomically(path, lambda f: fig.savefig(f, format="png"))
    return path
