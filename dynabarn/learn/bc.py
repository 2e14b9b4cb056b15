"""Behaviour cloning (paper Sec. IV-b): the Fig. 4 actor regressed onto demonstrated actions."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dynabarn.demos.dataset import load_dataset
from dynabarn.planners.learned.models import Actor, save_policy
from dynabarn.planners.learned.spaces import command_to_action


@dataclass
class BCReport:
    epochs: int
    rows: int
    losses: list[float]
    seconds: float


def fit_actor(
    actor: Actor,
    optim,
    obs: torch.Tensor,
    target: torch.Tensor,
    *,
    epochs: Iterable,
    batch_size: int,
    permutation: Callable[[int], Sequence[int]],
) -> list[float]:
    """Regress the actor onto the target actions by mean squared error: one pass over the
    rows per item of `epochs`, in minibatches taken in `permutation(n)` order. Returns each
    pass's mean loss. Behaviour cloning here and TD3's start share it."""
    losses = []
    for _ in epochs:
        perm = permutation(len(obs))
        total = 0.0
        for i in range(0, len(obs), batch_size):
            idx = perm[i : i + batch_size]
            loss = torch.mean((actor(obs[idx]) - target[idx]) ** 2)
            optim.zero_grad()
            loss.backward()
            optim.step()
            total += float(loss.detach()) * len(idx)
        losses.append(total / len(obs))
    return losses


def train_bc(
    data: Path,
    out: Path,
    *,
    epochs: int = 30,
    batch_size: int = 256,
    lr: float = 1e-3,
    seed: int = 0,
    progress=None,
) -> BCReport:
    """Fit the actor to (state, action) rows of a dataset by mean squared error."""
    ds = load_dataset(data)
    import json

    lookahead = float(json.loads(str(ds["metadata"]))["lookahead"])
    obs = torch.from_numpy(np.concatenate([ds["scans"], ds["local_goal"]], axis=1).astype(np.float32))
    target = torch.from_numpy(command_to_action(ds["actions"][:, 0], ds["actions"][:, 1]))
    torch.manual_seed(seed)
    gen = torch.Generator().manual_seed(seed)
    actor = Actor(lookahead)
    optim = torch.optim.Adam(actor.parameters(), lr=lr)
    t0 = time.perf_counter()
    losses = fit_actor(
        actor,
        optim,
        obs,
        target,
        epochs=range(epochs) if progress is None else progress(range(epochs)),
        batch_size=batch_size,
        permutation=lambda n: torch.randperm(n, generator=gen),
    )
    seconds = time.perf_counter() - t0
    save_policy(
        actor,
        out,
        kind="bc",
        lookahead=lookahead,
        notes={"data": Path(data).name, "rows": len(obs), "epochs": epochs, "final_loss": losses[-1]},
    )
    return BCReport(epochs=epochs, rows=len(obs), losses=losses, seconds=seconds)
