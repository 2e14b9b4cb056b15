"""DAgger (Ross et al. 2011) with a privileged teacher: the `dagger` planner's training.

Iteration i: the student drives `episodes` procedural training worlds (`split="train"`,
fresh worlds every iteration) in `DynaBARN-v0`, except that at every step the teacher's
command is executed instead with probability beta_i = `beta_decay` ** i (iteration 0:
the teacher alone, i.e. behaviour cloning's data); the teacher, which sees the obstacles'
true present positions and velocities (`oracle_present`), labels every state the robot
reaches, whoever drove. The labelled states join one dataset (aggregation), and the
student is trained on all of it (Adam), continuing from its last weights: by classifying
the teacher's commands among its candidates (cross-entropy, `head="classify"`), or by
regression onto its normalised actions (mean squared error, `head="regress"`). After each
iteration the student alone drives a fixed set of validation worlds (another seed
namespace): the learning curve.

Collection runs in `workers` processes (the teacher's search is most of the time); an
episode's data depends only on the weights, the seed and the world, so results do not
depend on which worker ran what. Resumable: every finished iteration is on disk (its data
in `data/`, the weights and the optimiser in `state.pt`); running the same command again
continues after the last one.
"""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import torch

from dynabarn.errors import DynabarnError
from dynabarn.files import save_atomically, write_atomically
from dynabarn.learn.configs import DEVICES, DaggerConfig, completed_config, resuming, saved_config
from dynabarn.learn.dagger_rollout import EpisodeData, run_episodes, student_from
from dynabarn.learn.split import describe_split
from dynabarn.planners.learned.models import load_tensors, save_tensors
from dynabarn.planners.learned.spaces import HEADS, command_to_action
from dynabarn.planners.learned.student import StudentActor, save_student, student_for
from dynabarn.planners.registry import get_planner
from dynabarn.processes import safe_path_for_children, worker_start

STATE, LOG, DATA = "state.pt", "train.log", "data"


@dataclass
class DaggerReport:
    iterations: list[dict] = field(default_factory=list)
    final: dict | None = None
    fingerprints: list[str] = field(default_factory=list)
    seconds: float = 0.0


def _log(out: Path, line: str) -> None:
    with (out / LOG).open("a") as f:
        f.write(line + "\n")


HOW_IT_RUNS = ("threads", "workers", "device", "warp_envs")
"""Settings that say how a run runs, not what it does (left out of its policy file)."""
RUN_LENGTH = ("iterations", "final_updates", *HOW_IT_RUNS)
"""Settings a run may change when resumed: where it ends and how it runs, not what it did."""


def _identity(cfg: dict | None) -> dict | None:
    if cfg is None:
        return None
    return {k: v for k, v in completed_config(cfg).items() if k not in RUN_LENGTH}


def _rates(eps: list[EpisodeData]) -> dict:
    out = {"episodes": len(eps), "success": float(np.mean([e.outcome == "success" for e in eps])) if eps else 0.0}
    for d in ("easy", "medium", "hard"):
        sub = [e.outcome == "success" for e in eps if e.difficulty == d]
        out[f"success_{d}"] = float(np.mean(sub)) if sub else None
    return out


def _resume(out: Path, actor: StudentActor, opt, data: Dataset, width: int) -> tuple[int, DaggerReport]:
    """Weights, optimiser, report and data of the finished iterations, from the checkpoint
    (tensors and plain data only: `weights_only`, no pickled code); one line if it is damaged."""
    with resuming(out):
        state = load_tensors(out / STATE)
        actor.load_state_dict(state["actor"])
        opt.load_state_dict(state["optimizer"])
        report = DaggerReport(**state["report"])
        data.load(len(report.iterations), width)
    return len(report.iterations), report


def fitting_device(choice: str) -> str:
    """`auto`, `cpu` or `cuda` as the device the student is fitted on; one line where CUDA is
    asked for and PyTorch sees none."""
    if choice not in DEVICES:
        raise DynabarnError(f"device {choice!r}: use one of {', '.join(DEVICES)}")
    if choice == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if choice == "cuda" and not torch.cuda.is_available():
        raise DynabarnError("device 'cuda': PyTorch sees no CUDA GPU here (use --device cpu or auto)")
    return choice


def _cpu_weights(actor: StudentActor) -> dict:
    """The student's weights for the collection workers (CPU tensors, wherever it is fitted)."""
    return {k: v.detach().to("cpu", copy=True) for k, v in actor.state_dict().items()}


def _validate(pool, cfg: DaggerConfig, actor: StudentActor) -> list[EpisodeData]:
    """The student alone on the fixed validation worlds."""
    weights = _cpu_weights(actor)
    return run_episodes(pool, cfg, "validation", range(cfg.validation_episodes), beta=0.0, weights=weights, label=False)


def _collect(pool, cfg: DaggerConfig, ks, beta: float, weights: dict | None, device: str) -> list[EpisodeData]:
    """An iteration's labelled training episodes: in the workers on the C engine, or in one
    Warp batch on `device` (`learn.warp_dagger`)."""
    if cfg.env_backend == "warp":
        from dynabarn.learn.warp_dagger import collect_on_warp

        actor = student_from(cfg, weights)
        actor = None if actor is None else actor.to(device)
        return collect_on_warp(
            cfg, ks, beta=beta, actor=actor, device=device, num_envs=cfg.warp_envs, workers=cfg.workers
        )
    return run_episodes(pool, cfg, "train", ks, beta=beta, weights=weights, label=True)


def _checkpoint(out: Path, actor: StudentActor, opt, report: DaggerReport, line: dict) -> None:
    """Everything a resumed run needs, then the log line that says it is there."""
    state = {"actor": actor.state_dict(), "optimizer": opt.state_dict(), "report": asdict(report)}
    save_tensors(out / STATE, state)
    _log(out, json.dumps(line))


class Dataset:
    """The aggregated states (float16 features) and the teacher's actions, iteration files on disk."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)
        self.x: list[np.ndarray] = []
        self.y: list[np.ndarray] = []

    def add(self, iteration: int, eps: list[EpisodeData]) -> int:
        x = np.concatenate([e.features for e in eps]).astype(np.float16)
        y = np.concatenate([e.labels for e in eps]).astype(np.float32)
        path = self.folder / f"iteration_{iteration:03d}.npz"
        save_atomically(path, lambda f: np.savez(f, x=x, y=y))
        self.x.append(x)
        self.y.append(y)
        return len(x)

    def load(self, iterations: int, width: int | None = None) -> None:
        """The first `iterations` files, each checked: rows of the features' `width` (of one
        width where None), one (v, w) label per row, finite numbers (ValueError otherwise: a
        resumed run never trains on NaN features or on rows another student was fed)."""
        for i in range(iterations):
            path = self.folder / f"iteration_{i:03d}.npz"
            with np.load(path, allow_pickle=False) as z:
                x, y = z["x"], z["y"]
            width = width if width is not None else (self.x[0].shape[1] if self.x else None)
            if x.ndim != 2 or y.shape != (len(x), 2) or (width is not None and x.shape[1] != width):
                raise ValueError(f"{path.name}: arrays of shapes {x.shape} and {y.shape} do not fit the run's")
            if not (np.isfinite(x).all() and np.isfinite(y).all()):
                raise ValueError(f"{path.name}: holds NaN or infinite values")
            self.x.append(x)
            self.y.append(y)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return np.concatenate(self.x), np.concatenate(self.y)


def teacher_classes(cfg: DaggerConfig) -> np.ndarray | None:
    """The classifier's classes: every (v, w) the teacher chooses among, as normalised
    actions (None for the regression head)."""
    if cfg.head == "regress":
        return None
    commands = get_planner(cfg.teacher).command_set()  # declared: Planner.command_set
    if commands is None:
        raise DynabarnError(f"head 'classify' needs a teacher choosing among (v, w) samples; {cfg.teacher} does not")
    commands = np.asarray(commands, dtype=float)
    return command_to_action(commands[:, 0], commands[:, 1])


def fit(actor, opt, x: np.ndarray, y: np.ndarray, cfg: DaggerConfig, seed: int, *, updates=None, decay=False):
    """Adam steps (`cfg.updates`) on batches drawn from (x, y), the learning rate falling
    linearly to 0 with `decay`; mean loss of the last tenth. The loss: mean squared error
    of the action (regression head) or cross-entropy of the teacher's class (classifier)."""
    rng = np.random.default_rng(seed)
    actor.train()
    losses = []
    classify = actor.classes is not None
    device = next(actor.parameters()).device
    xt = torch.from_numpy(x)  # on the CPU: a batch at a time goes to the device
    yt = torch.from_numpy(actor.class_labels(y)) if classify else torch.from_numpy(y)
    loss_of = torch.nn.functional.cross_entropy if classify else torch.nn.functional.mse_loss
    n = cfg.updates if updates is None else updates
    for k in range(n):
        if decay:
            for group in opt.param_groups:
                group["lr"] = cfg.lr * (1.0 - k / n)
        idx = torch.from_numpy(rng.integers(0, len(x), cfg.batch_size))
        loss = loss_of(actor(xt[idx].to(device).float()), yt[idx].to(device))
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    actor.eval()
    return float(np.mean(losses[-max(1, len(losses) // 10) :]))


# Over 80 lines on purpose: the DAgger loop as the algorithm box reads (collect with the
# mixed policy, relabel, aggregate, fit, validate), with its checkpoint and resume around it.
def train_dagger(cfg: DaggerConfig, out_dir: Path, *, progress=None) -> DaggerReport:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    features = cfg.features()
    if cfg.head not in HEADS:
        raise DynabarnError(f"head {cfg.head!r}: use one of {', '.join(HEADS)}")
    device = fitting_device(cfg.device)
    # Initialised on the CPU (the same weights for every device), then moved.
    actor = student_for(features, teacher_classes(cfg), cfg.encoder).to(device)
    opt = torch.optim.Adam(actor.parameters(), lr=cfg.lr)
    report = DaggerReport()
    data = Dataset(out / DATA)
    config_path = out / "config.json"
    done = 0
    if (out / STATE).is_file():
        old, new = _identity(saved_config(config_path)), _identity(json.loads(json.dumps(asdict(cfg))))
        if old is None:  # a checkpoint of no known run: resuming it would guess what it was
            raise DynabarnError(
                f"{out} holds a checkpoint ({STATE}) but no config.json that says what run it is; choose another --out"
            )
        if old != new:
            differ = ", ".join(
                f"{k} {old.get(k)!r} (asked: {new.get(k)!r})"
                for k in sorted(old.keys() | new.keys())
                if old.get(k) != new.get(k)
            )
            raise DynabarnError(
                f"{out} holds a run with another configuration ({differ}): give its options, or choose another --out"
            )
        done, report = _resume(out, actor, opt, data, features.size())
    write_atomically(config_path, json.dumps(asdict(cfg), indent=1))
    bar = progress(total=cfg.iterations, initial=done) if progress else None
    ctx = get_context("spawn")  # workers import torch afresh: no fork of a threaded parent
    safe_path_for_children()  # a spawned worker starts as `python -c`: never from the current folder
    t0 = time.perf_counter() - report.seconds
    # The collectors end with this process, even when it is killed with SIGKILL.
    with ProcessPoolExecutor(
        max_workers=cfg.workers, mp_context=ctx, initializer=worker_start, initargs=(os.getpid(),)
    ) as pool:
        for it in range(done, cfg.iterations):
            report.final = None  # a run extended after its final fit fits again at its new end
            beta = cfg.beta_decay**it
            weights = None if it == 0 else _cpu_weights(actor)
            ks = range(it * cfg.episodes, (it + 1) * cfg.episodes)
            eps = _collect(pool, cfg, ks, beta, weights, device)
            rows = data.add(it, eps)
            report.fingerprints.extend(e.fingerprint for e in eps)
            x, y = data.arrays()
            loss = fit(actor, opt, x, y, cfg, seed=cfg.seed * 1000 + it)
            val = _validate(pool, cfg, actor)
            entry = {
                "iteration": it,
                "beta": beta,
                "rows": rows,
                "dataset": len(x),
                "loss": loss,
                "collection": _rates(eps),
                "teacher_share": float(np.mean([e.teacher_share for e in eps])),
                "validation": _rates(val),
                "seconds": time.perf_counter() - t0,
                "device": device,
            }
            report.iterations.append(entry)
            report.seconds = entry["seconds"]
            _checkpoint(out, actor, opt, report, entry)
            if bar is not None:
                bar.update(1)
        if cfg.final_updates and report.final is None and report.iterations:
            x, y = data.arrays()
            loss = fit(actor, opt, x, y, cfg, seed=cfg.seed * 1000 + 999, updates=cfg.final_updates, decay=True)
            for group in opt.param_groups:
                group["lr"] = cfg.lr
            report.final = {
                "updates": cfg.final_updates,
                "loss": loss,
                "validation": _rates(_validate(pool, cfg, actor)),
            }
            report.seconds = time.perf_counter() - t0
            _checkpoint(out, actor, opt, report, {"final": report.final})
    if bar is not None:
        bar.close()
    split = describe_split("train", cfg.seed, tuple(cfg.profile_sets))
    trained_on = {**split, "worlds": len(set(report.fingerprints)), "fingerprints": sorted(set(report.fingerprints))}
    notes = _notes(cfg, report, device)
    save_student(actor.cpu(), out / "policy.pt", features=features, trained_on=trained_on, notes=notes)
    write_atomically(out / "training.json", json.dumps({"config": asdict(cfg), **asdict(report)}, indent=1))
    plot_learning_curve(report, out / "learning_curve.png")
    return report


def _notes(cfg: DaggerConfig, report: DaggerReport, device: str) -> dict:
    """What the policy file says of its run: what it did, not how it ran (workers, threads,
    seconds: a CPU run's file is the same bytes whatever they were), except the device of a
    GPU run, whose kernels round differently."""
    config = {k: v for k, v in asdict(cfg).items() if k not in HOW_IT_RUNS}
    last = report.iterations[-1] if report.iterations else None
    notes = {"config": config, "last_iteration": last and {k: v for k, v in last.items() if k != "seconds"}}
    notes["final"] = report.final
    if device != "cpu":
        notes["device"] = f"{device} ({torch.cuda.get_device_name()})" if device == "cuda" else device
    return notes


def plot_learning_curve(report: DaggerReport, path: Path) -> Path:
    from matplotlib.figure import Figure

    its = [e["iteration"] for e in report.iterations]
    fig = Figure(figsize=(6, 3.5), dpi=120)
    ax = fig.subplots()
    for d, style in (("easy", "o-"), ("medium", "s-"), ("hard", "^-")):
        ax.plot(its, [e["validation"][f"success_{d}"] for e in report.iterations], style, label=f"student, {d}")
    ax.plot(its, [e["beta"] for e in report.iterations], "k:", label="teacher's share of control")
    if report.final is not None and its:
        end = its[-1] + 1
        for d, marker in (("easy", "o"), ("medium", "s"), ("hard", "^")):
            ax.plot([end], [report.final["validation"][f"success_{d}"]], marker, color="black", fillstyle="none")
        ax.annotate("after the final fit", (end, report.final["validation"]["success"]), fontsize=7)
    ax.set_xlabel("DAgger iteration")
    ax.set_ylabel("success rate (validation worlds)")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("DAgger student on unseen procedural worlds", fontsize=10)
    fig.tight_layout()
    save_atomically(path, lambda f: fig.savefig(f, format="png"))
    return path
