"""What observers of an episode receive: `EpisodeStart`, every `Tick`, robot poses, the result.

The MCAP recorder is one observer; the loop knows nothing of recording. The world, its
protocol and the simulation's configuration appear here as types only: an observer
written against this module loads neither MuJoCo nor the simulator."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, Protocol

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.interfaces.observation import EpisodeInfo

if TYPE_CHECKING:  # annotations only (what the simulator passes in)
    from dynabarn.metrics import EpisodeResult
    from dynabarn.protocol import EvalProtocol
    from dynabarn.sim_config import SimConfig
    from dynabarn.worlds.spec import WorldSpec


@dataclass(frozen=True, slots=True)
class EpisodeStart:
    """What observers learn when an episode starts."""

    world: WorldSpec
    world_path: Path
    world_sha256: str
    protocol: EvalProtocol
    planner: str
    planner_config: dict
    seed: int
    clock_offset: float
    config: SimConfig
    info: EpisodeInfo
    versions: dict
    world_xml: bytes = b""
    """The world file's bytes (what `world_sha256` hashes), attached to recordings."""


@dataclass(slots=True)
class Tick:
    """One control tick, as observers see it. Arrays are fresh (observers may keep them)."""

    time: float
    scan: np.ndarray  # (n_beams,)
    laser_pose: np.ndarray  # (3,) x, y, yaw of the laser in the world
    pose: np.ndarray  # (3,)
    velocity: np.ndarray  # (2,) measured v, w
    command: np.ndarray  # (2,) limited v, w sent to the robot
    raw_command: np.ndarray  # (2,) what the planner returned
    obstacles: np.ndarray  # (n_obstacles, 2)
    clearance: float
    distance_to_goal: float
    planner_ms: float
    debug: dict = field(default_factory=dict)
    tracks: object | None = None  # the planner's `Tracks` (dynabarn.perception), if it tracks obstacles


class Period(Protocol):
    """One control period as the loop hands it to `on_tick_period` and `on_poses_period`
    (`sim.period_record.PeriodRecord` is it): its Tick and its poses, each made on first
    request, and what a writer in another process makes them from."""

    @property
    def tick(self) -> Tick:
        """The period's Tick (scan, command, obstacles, the planner's debug and tracks)."""

    @property
    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """(times (n,), poses (n, 3)) at the pose rate since the last period."""

    def pose_span(self) -> tuple[int, int, bool]:
        """(first step, last step, ended): what the period's pose steps are made of."""

    def numbers(self) -> tuple:
        """The period's own numbers a Tick is made of (`recording.tick_rows.tick_from`)."""


class EpisodeObserver:
    """Receives an episode as it happens; override the hooks you need (each does nothing
    here). The loop calls `on_start`, then per control tick `on_tick` and `on_poses` (the
    robot's poses at the pose rate since the last tick), then `on_end` with the result.
    Raising `dynabarn.errors.EndEpisode` from `on_tick` ends the episode.

    Two more hooks take a control period's own record (`Period`) instead: `on_tick_period`
    hands `on_tick` the period's Tick and `on_poses_period` hands `on_poses` its poses,
    unless an observer overrides them (the recorder's writer process does: it makes the
    Tick elsewhere). The loop makes a period's
    Tick only for observers that override `on_tick` or `on_tick_period` (`listens`).

    An observer is an instance of this class; every hook is named in `HOOKS`, and the loop
    refuses an observer with any other `on_*` method (`check_hooks`), so a misspelt hook is
    an error, not a hook never called.
    """

    HOOKS: ClassVar[frozenset[str]] = frozenset(
        {"on_start", "on_tick", "on_poses", "on_end", "on_tick_period", "on_poses_period"}
    )

    def on_start(self, start: EpisodeStart) -> None:
        """The episode starts (world, protocol, planner, seed, versions)."""

    def on_tick(self, tick: Tick) -> None:
        """One control tick: the scan, the command, the obstacles."""

    def on_poses(self, times: np.ndarray, poses: np.ndarray) -> None:
        """Robot poses (n, 3) at `times` (n,) since the last call."""

    def on_end(self, result: EpisodeResult) -> None:
        """The episode's result."""

    def on_tick_period(self, period: Period) -> None:
        """One control period's record: by default its Tick, made now, to `on_tick`."""
        self.on_tick(period.tick)

    def on_poses_period(self, period: Period) -> None:
        """One control period's record: by default its poses, when there are any, to `on_poses`."""
        times, poses = period.poses
        if len(times):
            self.on_poses(times, poses)


def listens(observer: EpisodeObserver) -> tuple[bool, bool]:
    """(to ticks, to poses): whether the observer overrides a tick hook and a pose hook (the
    loop hands periods only to those that do, and makes no Tick for the others)."""
    cls, base = type(observer), EpisodeObserver
    ticks = cls.on_tick is not base.on_tick or cls.on_tick_period is not base.on_tick_period
    poses = cls.on_poses is not base.on_poses or cls.on_poses_period is not base.on_poses_period
    return ticks, poses


def check_hooks(observer: object) -> None:
    """Refuse what is not an `EpisodeObserver`, and an observer with an `on_*` method that is
    not a hook (`EpisodeObserver.HOOKS`): it would never be called."""
    if not isinstance(observer, EpisodeObserver):
        raise DynabarnError(
            f"observer {type(observer).__name__} is not a dynabarn.interfaces.EpisodeObserver (subclass it)"
        )
    unknown = sorted(
        name for name in dir(type(observer)) if name.startswith("on_") and name not in EpisodeObserver.HOOKS
    )
    if unknown:
        raise DynabarnError(
            f"observer {type(observer).__name__}: {', '.join(unknown)} is not a hook (hooks: "
            f"{', '.join(sorted(EpisodeObserver.HOOKS))})"
        )
