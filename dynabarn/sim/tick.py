"""The one way a `Tick` is made from a control period's numbers (`tick_from`, with the
episode's fixed `TickFacts`): in the episode's process (`Episode.tick_record`) and in the
recorder's writer process (`recording.tick_rows`), so both make the same bits."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dynabarn.determinism import RECORD_RESOLUTION, snap
from dynabarn.interfaces.events import Tick
from dynabarn.metrics import footprint_clearance_at
from dynabarn.robot import JACKAL, mounted_pose

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
