"""The training commands' configurations, without PyTorch or Gymnasium: `dynabarn-train
--help` reads its options, their ranges and defaults from these fields (metadata "cli":
(low, high, help)), so each value is written once."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from dynabarn.learn.split import DEFAULT_PROFILE_SETS
from dynabarn.limits import MAX_JOBS, MAX_SEED
from dynabarn.planners.learned.features import FeatureConfig
from dynabarn.processes import usable_cores


def option(default: Any, low: float, high: float, text: str) -> Any:
    """A field that `dynabarn-train` offers as `--name`, checked against [low, high]."""
    return field(default=default, metadata={"cli": (low, high, text)})


def cli_options(config: type) -> list[tuple[str, type, float, float, str, Any]]:
    """(name, type, low, high, help, default) of each field a command offers."""
    out = []
    for f in fields(config):
        if "cli" in f.metadata:
            low, high, text = f.metadata["cli"]
            out.append((f.name, type(f.default), low, high, text, f.default))
    return out


@dataclass
class TD3Config:
    steps: int = option(80_000, 1, 100_000_000, "environment steps in total")
    envs: int = option(1, 1, MAX_JOBS, "parallel environments (one process each when > 1)")
    world_set: str = "paper60"
    difficulty: str | None = "all"
    protocol: str = "barn"
    lookahead: float = 2.0
    gamma: float = 0.99
    tau: float = 0.005
    lr: float = 3e-4
    batch_size: int = 256
    buffer_size: int = 200_000
    start_steps: int = option(0, 0, 100_000_000, "uniformly random actions first")
    exploration_noise: float = 0.1
    policy_noise: float = 0.2
    noise_clip: float = 0.5
    policy_delay: int = 2
    update_every: int = option(2, 1, 1_000, "environment steps per gradient update")
    demos: int = option(
        200, 0, 100_000, "oracle demonstration episodes in the replay buffer (0: none, the paper's TD3)"
    )
    demo_share: float = option(0.25, 0.0, 1.0, "share of every batch drawn from the demonstrations")
    bc_epochs: int = option(30, 0, 10_000, "behaviour-cloning epochs on the demonstrations before TD3")
    bc_lr: float = option(1e-3, 1e-8, 1.0, "Adam learning rate of the behaviour cloning")
    critic_warmup: int = option(2_000, 0, 1_000_000, "critic-only updates on the demonstrations before TD3")
    actor_start: int = option(
        5_000, 0, 100_000_000, "steps of critic-only updates on the policy's own experience first"
    )
    bc_weight: float = option(5.0, 0.0, 100.0, "weight of the actor's distance to demonstrated actions (TD3+BC)")
    bc_decay_steps: int = option(100_000, 1, 100_000_000, "steps over which bc_weight decays linearly to 0")
    eval_every: int = option(10_000, 1, 100_000_000, "steps between evaluations and checkpoints")
    eval_episodes: int = option(30, 1, 10_000, "episodes per evaluation (training worlds, seeds of their own)")
    threads: int = option(2, 1, MAX_JOBS, "PyTorch threads (and demonstration processes)")
    seed: int = option(0, 0, MAX_SEED, "seed of torch, the buffers and the environments")

    def env_kwargs(self) -> dict:
        return {
            "world_set": self.world_set,
            "difficulty": self.difficulty,
            "protocol": self.protocol,
            "lookahead": self.lookahead,
        }


@dataclass
class PPOConfig:
    """`dynabarn-train ppo` (`learn.ppo`): defaults sized for a GPU."""

    num_envs: int = option(4096, 1, 1 << 20, "worlds stepped at once on the device")
    rollout: int = option(32, 1, 10_000, "control periods of every world per iteration")
    iterations: int = option(200, 1, 1_000_000, "rollouts and updates in total")
    epochs: int = option(4, 1, 100, "passes over a rollout")
    minibatches: int = option(8, 1, 100_000, "minibatches per pass")
    gamma: float = option(0.99, 0.0, 1.0, "discount")
    gae_lambda: float = option(0.95, 0.0, 1.0, "GAE's lambda")
    clip: float = option(0.2, 0.01, 0.99, "PPO's ratio clip")
    lr: float = option(3e-4, 1e-8, 1.0, "Adam learning rate")
    value_coef: float = option(0.5, 0.0, 100.0, "weight of the value loss")
    entropy_coef: float = option(0.0, 0.0, 1.0, "weight of the entropy bonus")
    max_grad_norm: float = option(0.5, 1e-6, 1e6, "gradient norm clipped to this")
    init_log_std: float = option(-0.5, -5.0, 2.0, "initial log standard deviation of the actions")
    seed: int = option(0, 0, MAX_SEED, "torch seed and the trials' seed")
    lookahead: float = 2.0
    notes: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.num_envs * self.rollout < self.minibatches:
            raise ValueError("ppo: fewer samples per iteration (num_envs x rollout) than minibatches")


SHIPPED_STUDENT_PROFILE_SETS = (*DEFAULT_PROFILE_SETS, "tier-dense", "tier-fast", "tier-mixed", "tier-combined")
"""What `dynabarn-train dagger` draws training worlds from by default: the paper's and the
release's profiles and the tiers' (their profiles, never their worlds), as the shipped
student did. The defaults are its recipe: `dynabarn-train dagger --out DIR` trains it."""
DEVICES = ("auto", "cpu", "cuda")
"""Where `dynabarn-train dagger` fits the student (`--device`)."""
TEACHERS = ("oracle_present", "predictive")
"""Who labels DAgger's states (`--teacher`): the oracle told the obstacles' true present
state (privileged), or `predictive`, the same search on the laser tracker's predictions
(what the student itself sees). Both choose among the same grid of commands."""
ENV_BACKENDS = ("c", "warp")
"""Where DAgger's training episodes are stepped: MuJoCo's C engine, or MuJoCo Warp."""
CORES = min(usable_cores(), MAX_JOBS)
"""DAgger's collection workers and fitting threads by default: collection and fitting take
turns, so each may use every core this process may run on."""


@dataclass
class DaggerConfig:
    iterations: int = option(10, 1, 10_000, "DAgger iterations (collect, relabel, aggregate, fit, validate)")
    episodes: int = option(240, 1, 1_000_000, "training episodes per iteration, each in a fresh procedural world")
    max_steps: int = option(400, 10, 100_000, "steps after which a training episode is cut")
    """A training episode ends after this many steps (40 s; the protocol allows 100 s): a
    student that stalls early in training would otherwise fill the dataset with waiting."""
    beta_decay: float = option(0.5, 0.0, 1.0, "the teacher drives with probability beta_decay ** iteration")
    teacher: str = "predictive"
    """Who labels every state (`TEACHERS`); recorded with the run and in the policy file.
    `predictive` taught the shipped student; `oracle_present` the earlier ones."""
    head: str = "classify"
    """The student's output (`spaces.HEADS`): `classify` among the teacher's candidate
    commands (cross-entropy; the shipped student), or `regress` the teacher's action (mean
    squared error; the first shipped student)."""
    encoder: str = "set"
    """How the student reads its inputs (`student.ENCODERS`): `set`, the scans by convolution
    and the tracks as a set (the shipped student), or `mlp`, the flat vector (the first)."""
    device: str = "auto"
    """Where the student is fitted (`auto`: a CUDA GPU when PyTorch sees one, else the CPU),
    and where a Warp collection steps its worlds. Validation runs on the CPU in the workers
    whatever it is."""
    env_backend: str = "c"
    """Where the training episodes are stepped (`ENV_BACKENDS`): `c`, MuJoCo's C engine in
    the collection workers; `warp`, one MuJoCo Warp batch on `device` (`learn.warp_dagger`,
    the gpu extra), the same episodes within the Warp backend's tolerances."""
    warp_envs: int = option(256, 1, 65_536, "environments of the Warp batch (with --env-backend warp)")
    updates: int = option(4000, 1, 100_000_000, "gradient steps per iteration over the whole aggregated dataset")
    final_updates: int = option(0, 0, 100_000_000, "updates after the last iteration, the learning rate falling to 0")
    """After the last iteration, this many more updates on the whole dataset with the
    learning rate falling linearly to 0 (then one more validation)."""
    batch_size: int = option(512, 1, 1_000_000, "rows per gradient step")
    lr: float = option(1e-3, 1e-8, 1.0, "Adam learning rate")
    validation_episodes: int = option(60, 0, 100_000, "student-only episodes on validation worlds per iteration")
    history: int = option(2, 0, 16, "earlier scans the student sees (0: the paper's single scan)")
    history_every: int = option(2, 1, 50, "control ticks between history frames")
    velocity: bool = True
    static_map: bool = False
    """The known map's ranges along the pooled beams among the inputs (`FeatureConfig.static_map`,
    `--static-map`): what its teacher plans on. Off in the shipped `dagger`'s recipe;
    `dagger_map.pt` (issue 57) trained with it."""
    tracks: int = option(16, 0, 64, "laser-tracker tracks the student sees, nearest first (0: no tracker)")
    protocol: str = "barn"
    workers: int = option(CORES, 1, MAX_JOBS, "collection processes (default: the cores this process may use)")
    threads: int = option(CORES, 1, MAX_JOBS, "PyTorch threads for fitting (default: the cores this process may use)")
    seed: int = option(0, 0, MAX_SEED, "seed of the split, the trials, the coin and torch")
    profile_sets: list[str] = field(default_factory=lambda: list(SHIPPED_STUDENT_PROFILE_SETS))

    def __post_init__(self) -> None:
        """Names checked here, where the run is configured (a `DynabarnError` line), not first
        inside the collection workers."""
        from dynabarn.errors import DynabarnError
        from dynabarn.learn.split import training_profile
        from dynabarn.protocol import get_protocol

        get_protocol(self.protocol)
        if self.teacher not in TEACHERS:
            raise DynabarnError(f"teacher {self.teacher!r}: use one of {', '.join(TEACHERS)}")
        if self.env_backend not in ENV_BACKENDS:
            raise DynabarnError(f"env_backend {self.env_backend!r}: use one of {', '.join(ENV_BACKENDS)}")
        if isinstance(self.profile_sets, str) or not self.profile_sets:
            raise DynabarnError(f"profile_sets {self.profile_sets!r}: give one or more profile set or tier names")
        for name in self.profile_sets:
            training_profile(name)

    def features(self) -> FeatureConfig:
        return FeatureConfig(
            history=self.history,
            history_every=self.history_every,
            static_map=self.static_map,
            velocity=self.velocity,
            tracks=self.tracks,
        )


BEFORE_THE_FIELD = {
    "head": "regress",
    "teacher": "oracle_present",
    "encoder": "mlp",
    "profile_sets": list(DEFAULT_PROFILE_SETS),
}
"""What a DAgger run written before a field existed did, where that is not the field's
default: every student before the classifier regressed; before `--teacher`, `--encoder`
and `--profile-sets` every run was taught by `oracle_present`, flat, on the paper's and
the release's profiles."""


def completed_config(saved: dict) -> dict:
    """A DAgger run's saved configuration (its `config.json`) with every field it predates
    filled in as the run did it (`BEFORE_THE_FIELD`, else the field's default)."""
    return {**asdict(DaggerConfig()), **BEFORE_THE_FIELD, **saved}


def saved_config(path: Path) -> dict | None:
    """The configuration a run folder holds (its `config.json`), None where it has none;
    one `DynabarnError` line where the file is not a JSON object."""
    from dynabarn.errors import DynabarnError

    if not path.is_file():
        return None
    try:
        saved = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError, RecursionError):
        saved = None
    if not isinstance(saved, dict):
        raise DynabarnError(f"{path}: not a training configuration (not JSON, or not an object); use another --out")
    return saved


@contextlib.contextmanager
def resuming(out: Path) -> Iterator[None]:
    """Reading a run's checkpoint back: any failure (PyTorch's and numpy's refusals run to a
    page) is one `DynabarnError` line that names the run and their first line."""
    from dynabarn.errors import DynabarnError

    try:
        yield
    except Exception as exc:
        first = str(exc).strip().splitlines()[0][:160] if str(exc).strip() else ""
        raise DynabarnError(f"{out}: cannot resume from its checkpoint ({type(exc).__name__}: {first})") from None
