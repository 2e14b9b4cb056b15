"""`bc` and `td3`: the learned baselines as planners (needs the `learn` extra).

Each runs the Fig. 4 actor on the paper's observation: the 720 ranges and the local goal
(g_x, g_y) from the Dijkstra global plan `lookahead` metres ahead (the lookahead the
policy was trained with). `policy=FILE` (`--policy FILE`) chooses the weights; without it
the policy shipped in `dynabarn/policies/` is used. Files load with
`torch.load(weights_only=True)`.
"""

from __future__ import annotations

import contextlib
import hashlib
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar

from dynabarn.errors import LEARN_EXTRA, LEARN_INSTALL, DynabarnError, NotInstalledHere
from dynabarn.interfaces import EpisodeInfo, Observation, Planner
from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.planners.learned.features import Features
from dynabarn.planners.learned.spaces import action_to_command, policy_input
from dynabarn.planners.learned.trained_on import check_unseen, trained_fingerprints

SHIPPED = Path(__file__).resolve().parents[2] / "policies"
DEFAULT_STUDENT = "dagger_predictive.pt"
"""The student `dagger` drives without `policy=`: the `set` network taught by `predictive`
(issue 44). The earlier students stay in `SHIPPED` under their own names (`dagger.pt`, the
first; `dagger_set.pt`, taught by `oracle_present`), so every result that names one still
runs it."""


class PolicyFilePlanner(Planner):
    """What every planner driven by a policy file shares: PyTorch, and the file's identity
    in results (the shipped policy by its place in the package, so results and recordings
    read the same wherever the package is installed; any other by its path and content)."""

    external_options: ClassVar[dict[str, str]] = {"policy": "a policy file it loads"}
    recorded_only: ClassVar[tuple[str, ...]] = ("policy_sha256", "kind", "lookahead", "head", "features")
    """What the policy file says of itself (its content, its kind, its inputs), recorded beside `policy`."""

    def _torch_or_refuse(self, what: str):
        try:
            import torch
        except ImportError:
            raise NotInstalledHere(f"planner {what!r} needs {LEARN_EXTRA}", LEARN_INSTALL) from None
        from threadpoolctl import ThreadpoolController

        self._torch = torch
        self._blas = ThreadpoolController().select(user_api="blas")  # the BLAS libraries loaded by now
        return torch

    @contextlib.contextmanager
    def _one_decision(self) -> Iterator[None]:
        """Around one network call: no autograd, one PyTorch intra-op thread and one BLAS
        thread (numpy's, where `dagger` runs its network). A decision is a batch of one,
        which more threads cannot share out; on a busy machine they wait on each other (the
        set student's call took 1.8 ms with two PyTorch threads where one took 0.75, both
        cores busy; the flat student's in numpy 4.3-6.5 ms with BLAS's default threads
        beside two busy loops, 2.2-2.7 with one). The process's own counts are back after
        the call; a sweep's workers have one thread of each already."""
        torch = self._torch
        threads = torch.get_num_threads()
        if threads != 1:
            torch.set_num_threads(1)
        try:
            with torch.inference_mode(), self._blas.limit(limits=1):
                yield
        finally:
            if threads != 1:
                torch.set_num_threads(threads)

    def _identify(self, path: Path) -> None:
        """After the file loaded: its path and sha256."""
        self.policy_path = str(path)
        self.policy_sha256 = hashlib.sha256(path.read_bytes()).hexdigest()

    def policy_identity(self) -> dict:
        shipped = Path(self.policy_path).resolve().parent == SHIPPED
        return {
            "policy": f"dynabarn/policies/{Path(self.policy_path).name}" if shipped else self.policy_path,
            "policy_sha256": self.policy_sha256,
        }

    def versions(self) -> dict[str, str]:
        return {"torch": self._torch.__version__}


class LearnedPlanner(PolicyFilePlanner):
    kind = "bc"

    def __init__(self, policy: str | None = None) -> None:
        self._torch_or_refuse(self.kind)
        from dynabarn.planners.learned.models import load_policy

        path = Path(policy) if policy else SHIPPED / f"{self.kind}.pt"
        self.actor, self.header = load_policy(path)
        # Inference in float64: PyTorch's CPU kernels (AVX2, AVX-512, threads) differ in the
        # last bits, which float32 would leave at 1e-7 (too close to the command grid).
        self.actor.double()
        self.lookahead = float(self.header.get("lookahead", 2.0))
        self._identify(path)

    def config(self) -> dict:
        return {**self.policy_identity(), "kind": self.header.get("kind"), "lookahead": self.lookahead}

    def reset(self, info: EpisodeInfo) -> None:
        self.global_planner = GlobalPlanner.for_robot(info.walls, info.goal, info.footprint, info.static_obstacles)

    def act(self, obs: Observation) -> tuple[float, float]:
        g = self.global_planner.local_goal_in_robot(obs.pose, self.lookahead)
        x = policy_input(obs.scan, g)[None]
        with self._one_decision():
            a = self.actor(self._torch.from_numpy(x)).numpy()[0]
        return action_to_command(a)


class BCPlanner(LearnedPlanner):
    name = "bc"
    kind = "bc"


class TD3Planner(LearnedPlanner):
    name = "td3"
    kind = "td3"


class PPOPlanner(LearnedPlanner):
    """`ppo`: an actor trained by `dynabarn-train ppo` on the Warp backend (none is shipped:
    `policy=FILE`)."""

    name = "ppo"
    kind = "ppo"

    def __init__(self, policy: str | None = None) -> None:
        if policy is None:
            raise DynabarnError("--planner ppo: none is shipped; train one (dynabarn-train ppo), give --policy FILE")
        super().__init__(policy)


class DaggerPlanner(PolicyFilePlanner):
    """`dagger`: the student of `dynabarn-train dagger` (a network over `Features`).

    It sees what its features name (the scan and the local goal; scan history, measured
    velocity and the laser tracker's tracks where its file says so), never the truth. It
    refuses to drive in a world its policy trained on (`trained_on.check_unseen`).
    """

    name = "dagger"

    def __init__(self, policy: str | None = None) -> None:
        self._torch_or_refuse(self.name)
        from dynabarn.planners.learned.numpy_student import NumpyStudent
        from dynabarn.planners.learned.student import load_student

        path = Path(policy) if policy else SHIPPED / DEFAULT_STUDENT
        actor, self.features_config, self.header = load_student(path)
        self.actor = actor.double()  # float64, as LearnedPlanner: far from the command grid
        # One decision at a time in numpy: a tenth of a millisecond, half the PyTorch call.
        self._decide = NumpyStudent(self.actor)
        self.features = Features(self.features_config)
        self.seen = trained_fingerprints(self.header["trained_on"])
        self._identify(path)

    def config(self) -> dict:
        # The head only where it is not the regression every earlier student had (their
        # results and recordings keep the configuration they were made with).
        head = {} if self.actor.head == "regress" else {"head": self.actor.head}
        return {**self.policy_identity(), "kind": "dagger", **head, "features": self.features_config.names()}

    def reset(self, info: EpisodeInfo) -> None:
        check_unseen(self.seen, info.world_fingerprint, self.policy_path)
        self.features.reset(info)

    def tracks(self):
        return self.features.last_tracks

    def act(self, obs: Observation) -> tuple[float, float]:
        x = self.features(obs)
        with self._one_decision():
            a = self._decide(x)
        return action_to_command(a)
