"""A control period's numbers as one row of float64 (`TickRows`): what the episode's process
sends the writer process (`recording.background`) and the writer turns back into a Tick.

A row holds the period's time, pose, velocity, commands, planner time, scan and obstacle
centres, then a flag: how the row was filled (a whole Tick, or the period's own numbers
from which the writer makes the Tick with `tick_from`, the clearance given or not). Every
number is float64 as it was, so the Tick the writer makes has the same bits. The robot's
poses travel beside the rows, a batch's at once (`recording.background`).
"""

from __future__ import annotations

import numpy as np

from dynabarn.interfaces.events import Tick
from dynabarn.sim.tick import tick_from

HOLDS_TICK, DERIVE_ALL, CLEARANCE_GIVEN = 1.0, 2.0, 3.0
"""What a row holds: a whole Tick, or a period's numbers from which the writer makes it
(`tick_from`), with the clearance computed in the episode's process or not."""


class TickRows:
    """Where each of a tick's numbers sits in its row (the scan's and obstacles' lengths
    are the episode's)."""

    @classmethod
    def for_episode(cls, start) -> TickRows:
        """The rows of an episode (`EpisodeStart`): its beams and its obstacles."""
        return cls(len(start.info.laser_angles), len(start.world.obstacles))

    def __init__(self, n_beams: int, n_obstacles: int) -> None:
        self.n, self.m = n_beams, n_obstacles
        self.obstacles = 16 + n_beams
        self.end = self.obstacles + 2 * n_obstacles
        self.width = self.end + 1  # then how the row was filled

    def pack(self, row: np.ndarray, tick: Tick) -> None:
        n = self.n
        row[0] = tick.time
        row[1:4] = tick.laser_pose
        row[4:7] = tick.pose
        row[7:9] = tick.velocity
        row[9:11] = tick.command
        row[11:13] = tick.raw_command
        row[13] = tick.clearance
        row[14] = tick.distance_to_goal
        row[15] = tick.planner_ms
        row[16 : 16 + n] = tick.scan
        row[self.obstacles : self.end] = tick.obstacles.ravel()
        row[-1] = HOLDS_TICK

    def pack_numbers(self, row: np.ndarray, numbers: tuple) -> None:
        """A period's own numbers (`PeriodRecord.numbers`): the writer makes the Tick."""
        t, scan, pose, velocity, command, raw, obstacles, planner_ms, clearance = numbers
        row[0] = t
        row[4:7] = pose
        row[7:9] = velocity
        row[9:11] = command
        row[11:13] = raw
        row[15] = planner_ms
        row[16 : 16 + self.n] = scan
        row[self.obstacles : self.end] = obstacles.ravel()
        if clearance is None:
            row[-1] = DERIVE_ALL
        else:
            row[13], row[-1] = clearance, CLEARANCE_GIVEN

    def unpack(self, row: np.ndarray, extra: tuple | None, facts) -> Tick:
        """The row's Tick: as packed, or made by `tick_from` from the period's numbers."""
        debug, tracks = extra if extra is not None else ({}, None)
        time, scan, pose = float(row[0]), row[16 : 16 + self.n].copy(), row[4:7].copy()
        velocity, command, raw_command = row[7:9].copy(), row[9:11].copy(), row[11:13].copy()
        obstacles = row[self.obstacles : self.end].reshape(self.m, 2).copy()
        planner_ms = float(row[15])
        if row[-1] != HOLDS_TICK:
            clearance = None if row[-1] == DERIVE_ALL else float(row[13])
            numbers = (time, scan, pose, velocity, command, raw_command, obstacles, planner_ms)
            return tick_from(*numbers, debug, tracks, facts, clearance)
        return Tick(
            time=time,
            scan=scan,
            laser_pose=row[1:4].copy(),
            pose=pose,
            velocity=velocity,
            command=command,
            raw_command=raw_command,
            obstacles=obstacles,
            clearance=float(row[13]),
            distance_to_goal=float(row[14]),
            planner_ms=planner_ms,
            debug=debug,
            tracks=tracks,
        )
