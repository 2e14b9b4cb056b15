"""The CPU's side of DAgger's collection on the Warp backend (`learn.warp_dagger`): for a
slice of the batch's environments, each episode's mirror `Episode`, student features,
teacher and coin, in this process or in a worker of its own.

The collection's process and its hosts share one set of buffers (`Buffers`, shared memory):
each period it writes every environment's scan, pose, velocity and step there and asks
every host to `observe` (features, the teacher's label, who drives); after the batch's step
it writes how each episode ended and asks every host to `settle` (finished episodes back as
`EpisodeData`, the next ones started, the ones cut by `max_steps` marked). A host's results
depend only on its environments' episodes, so the split over hosts changes nothing.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field

import numpy as np

from dynabarn.learn.dagger_rollout import EpisodeData, episode_draws
from dynabarn.learn.shared_worlds import shared_world
from dynabarn.planners.learned.features import Features
from dynabarn.planners.learned.spaces import command_to_action
from dynabarn.planners.registry import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.sim.episode import Episode

ENDS = (None, "success", "collision", "timeout")
"""`Buffers.ends`' codes: how an environment's episode ended in the last step (0: it goes on)."""


def end_codes(terminated: np.ndarray, truncated: np.ndarray, success: np.ndarray) -> np.ndarray:
    """`ENDS`' code of each environment's step: success, collision, timeout, or 0."""
    return np.where(terminated, np.where(success, 1, 2), np.where(truncated, 3, 0))


@dataclass(frozen=True)
class Plan:
    """An iteration's episodes: episode i is the split's world `ks[i]` (file `files[i]`,
    its `difficulties[i]` and `fingerprints[i]`), on trial `trials[i]`; environment w plays
    `queues[w]` in turn."""

    ks: list[int]
    files: list[str]
    difficulties: list[str]
    fingerprints: list[str]
    trials: list[int]
    queues: list[list[int]]


_DTYPES = {ctypes.c_float: np.float32, ctypes.c_double: np.float64, ctypes.c_int64: np.int64, ctypes.c_int8: np.int8}


class Buffers:
    """The collection's shared arrays for `n` environments and features of `size`."""

    LAYOUT = (
        ("scans", ctypes.c_float, 720),
        ("qpos", ctypes.c_double, 3),
        ("qvel", ctypes.c_double, 3),
        ("steps", ctypes.c_int64, 1),
        ("xs", ctypes.c_float, None),
        ("teacher", ctypes.c_float, 2),
        ("coin", ctypes.c_int8, 1),
        ("ends", ctypes.c_int8, 1),
        ("cut", ctypes.c_int8, 1),
        ("active", ctypes.c_int8, 1),
    )

    def __init__(self, raw: dict, n: int, size: int) -> None:
        self.raw, self.n, self.size = raw, n, size
        for name, kind, width in self.LAYOUT:
            a = np.frombuffer(raw[name], dtype=_DTYPES[kind])
            setattr(self, name, a.reshape(n, size if width is None else width) if width != 1 else a)

    @classmethod
    def allocate(cls, ctx, n: int, size: int) -> Buffers:
        raw = {name: ctx.RawArray(kind, n * (size if width is None else width)) for name, kind, width in cls.LAYOUT}
        return cls(raw, n, size)


@dataclass
class _Running:
    """One environment's episode in progress: its mirror, features, teacher and data."""

    index: int
    mirror: Episode
    features: Features
    teacher: object
    rng: np.random.Generator
    xs: list = field(default_factory=list)
    ys: list = field(default_factory=list)
    teacher_steps: int = 0
    steps: int = 0


class Host:
    """The CPU's side of environments `envs` (see the module docstring)."""

    def __init__(self, cfg, plan: Plan, envs: range, buffers: Buffers, *, beta: float, student: bool) -> None:
        self.cfg, self.plan, self.envs, self.buffers = cfg, plan, envs, buffers
        self.beta, self.student = beta, student
        self.protocol = get_protocol(cfg.protocol)
        self.templates = {i: shared_world(plan.files[i])[0] for w in envs for i in plan.queues[w]}
        self.played = dict.fromkeys(envs, 0)
        self.running = {w: self._start(w) for w in envs}
        self._mark_active()

    def _start(self, w: int) -> _Running | None:
        queue = self.plan.queues[w]
        if self.played[w] >= len(queue):
            return None
        i = queue[self.played[w]]
        cfg = self.cfg
        mirror = Episode(self.templates[i].fork(), self.protocol, seed=self.plan.trials[i], privileged=True)
        features, teacher = Features(cfg.features()), get_planner(cfg.teacher)
        features.reset(mirror.info)
        teacher.reset(mirror.info)
        _, rng = episode_draws(cfg, "train", self.plan.ks[i])  # the coin, as the C collection tosses it
        return _Running(i, mirror, features, teacher, rng)

    def _mark_active(self) -> None:
        for w, r in self.running.items():
            self.buffers.active[w] = r is not None

    def observe(self) -> None:
        """Each running episode's observation of the batch's state (the C engine's, made by
        its mirror), the student's features of it, the teacher's label, and the coin."""
        b = self.buffers
        for w, r in self.running.items():
            if r is None:
                continue
            mirror = r.mirror
            mirror.step = int(b.steps[w])
            mirror.sim.data.qpos[:3] = b.qpos[w]
            mirror.sim.data.qvel[:3] = b.qvel[w]
            mirror.place_obstacles()
            o = mirror.observe_scan(b.scans[w].astype(np.float64))
            b.xs[w] = x = r.features(o)
            b.teacher[w] = label = command_to_action(*r.teacher.act(o))
            b.coin[w] = teacher_drives = not self.student or r.rng.random() < self.beta
            r.teacher_steps += int(teacher_drives)
            r.xs.append(x.astype(np.float16))
            r.ys.append(label.astype(np.float32))
            r.steps += 1

    def settle(self) -> list[EpisodeData]:
        """The episodes that ended in the batch's last step (or reached `max_steps`: marked
        in `cut` for the batch to restart), finished; the next ones started."""
        b, done = self.buffers, []
        for w, r in self.running.items():
            b.cut[w] = 0
            if r is None:
                continue
            outcome = ENDS[b.ends[w]]
            if outcome is None and len(r.xs) >= self.cfg.max_steps:
                outcome, b.cut[w] = "cut", 1
            if outcome is not None:
                done.append(self._finish(r, outcome))
                self.played[w] += 1
                self.running[w] = self._start(w)
        self._mark_active()
        return done

    def _finish(self, r: _Running, outcome: str) -> EpisodeData:
        r.teacher.finish(outcome)
        n, size = len(r.xs), self.buffers.size
        return EpisodeData(
            k=self.plan.ks[r.index],
            difficulty=self.plan.difficulties[r.index],
            fingerprint=self.plan.fingerprints[r.index],
            outcome=outcome,
            steps=r.steps,
            teacher_share=r.teacher_steps / max(1, r.steps),
            features=np.stack(r.xs) if n else np.zeros((0, size), np.float16),
            labels=np.stack(r.ys) if n else np.zeros((0, 2), np.float32),
        )


def serve(conn, cfg, plan: Plan, envs: range, raw: dict, n: int, size: int, beta: float, student: bool, parent: int):
    """A worker's loop: a `Host` of `envs` answering the collection's `observe`, `settle` and
    `stop` over `conn` (its pipe)."""
    import torch

    from dynabarn.processes import worker_start

    worker_start(parent)
    torch.set_num_threads(1)
    host = Host(cfg, plan, envs, Buffers(raw, n, size), beta=beta, student=student)
    conn.send("ready")
    while True:
        command = conn.recv()
        if command == "observe":
            host.observe()
            conn.send(None)
        elif command == "settle":
            conn.send(host.settle())
        else:
            return
