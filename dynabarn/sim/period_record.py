"""What the loop hands observers each control period (`PeriodRecord`), and the one way a
`Tick` is made from a period's numbers (`tick_from`).

A `Tick` carries fresh copies and derived numbers (the laser's pose, the clearance, the
distance to the goal); making one costs the episode's process about 30 us a period, most
of it where caches are cold. The loop makes it, and the poses since the last period, only
when an observer asks (`PeriodRecord.tick`, `.poses`, made once for all observers). An
observer that takes the period's own numbers instead (`on_tick_period`,
`on_poses_period`: the writer-process recorder) makes the Tick elsewhere with `tick_from`
and `TickFacts`, and takes the poses of many periods at once (`pose_span`,
`Episode.pose_steps`): the same functions on the same numbers, so the same bits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from dynabarn.determinism import RECORD_RESOLUTION, snap
from dynabarn.interfaces.events import Tick
from dynabarn.metrics import footprint_clearance_at
from dynabarn.robot import JACKAL, mounted_pose

if TYPE_CHECKING:
    from dynabarn.sim.episode import Episode

HALF_FOOTPRINT = (JACKAL.length / 2, JACKAL.width / 2)


@dataclass(frozen=True)
class TickFacts:
    """What making a Tick needs beside a period's numbers, fixed for an episode."""

    laser_offset: np.ndarray  # (2,) the laser in the robot frame
    radii: np.ndarray  # (n,) the obstacles' radii
    goal: np.ndarray  # (2,)


def tick_from(
    time: float,
    scan: np.ndarray,
    pose: np.ndarray,
    velocity: np.ndarray,
    command: np.ndarray,
    raw_command: np.ndarray,
    obstacles: np.ndarray,
    planner_ms: float,
    debug: dict,
    tracks,
    facts: TickFacts,
    clearance: float | None = None,
) -> Tick:
    """The Tick of a period's numbers (arrays taken as they are: pass fresh ones). The
    clearance to cylinders is computed here; `clearance` gives one computed otherwise (a
    world of shapes, by the simulation's shape distance), already on the record grid."""
    if clearance is None:
        clearance = snap(
            footprint_clearance_at(pose[0], pose[1], pose[2], obstacles, facts.radii, HALF_FOOTPRINT),
            RECORD_RESOLUTION,
        )
    return Tick(
        time=time,
        scan=scan,
        # Where the laser was when the scan was cast, not where the physics since carried it.
        laser_pose=mounted_pose(pose, facts.laser_offset),
        pose=pose,
        velocity=velocity,
        command=command,
        raw_command=raw_command,
        obstacles=obstacles,
        clearance=clearance,
        distance_to_goal=math.hypot(facts.goal[0] - pose[0], facts.goal[1] - pose[1]),
        planner_ms=planner_ms,
        debug=debug,
        tracks=tracks,
    )


class PeriodRecord:
    """One control period for observers: its Tick and poses made on first request."""

    __slots__ = ("_poses", "_tick", "debug", "episode", "first", "tracks")

    def __init__(self, episode: Episode, debug: dict, tracks, first: int) -> None:
        self.episode, self.debug, self.tracks, self.first = episode, debug, tracks, first
        self._tick: Tick | None = None
        self._poses: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def tick(self) -> Tick:
        if self._tick is None:
            self._tick = self.episode.tick_record(self.debug, self.tracks)
        return self._tick

    @property
    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """(times, poses) at the pose rate since the last period (`Episode.poses_between`)."""
        if self._poses is None:
            self._poses = self.episode.poses_between(self.first)
        return self._poses

    def pose_span(self) -> tuple[int, int, bool]:
        """(first step, last step, ended): what `Episode.pose_steps` makes this period's
        pose steps of, later (the poses of steps already run never change)."""
        episode = self.episode
        return self.first, episode.step, episode.outcome is not None

    def numbers(self) -> tuple:
        """The period's own numbers for `tick_from`, as references (copy what you keep):
        (time, scan, pose, velocity, command, raw command (v, w), obstacles, planner ms,
        clearance: None unless the world's shapes need the simulation to compute it)."""
        return self.episode.period_numbers()


def observer_hooks(observers) -> tuple[list, list]:
    """Each observer's tick and pose hooks, taking a `PeriodRecord`: its `on_tick_period`
    where it has one, else its `on_tick` given the record's Tick; its `on_poses_period`
    where it has one, else its `on_poses` given the record's poses, when there are any."""

    def tick_hook(obs):
        own = getattr(obs, "on_tick_period", None)
        return own if own is not None else (lambda period, on_tick=obs.on_tick: on_tick(period.tick))

    def pose_hook(obs):
        own = getattr(obs, "on_poses_period", None)
        if own is not None:
            return own

        def on_poses(period, on_poses=obs.on_poses):
            times, poses = period.poses
            if len(times):
                on_poses(times, poses)

        return on_poses

    return [tick_hook(o) for o in observers], [pose_hook(o) for o in observers]
