"""Worlds compiled once per process and shared by every environment in it.

A vector environment's 32 worlds meeting `paper60`'s 60 would otherwise each compile and
plan every world they meet (1.4 ms for the simulation, 1.2 ms for the global plan): a
third of the steps' time in a short run. Each environment forks the shared simulation
(its own data and buffers, `Simulation.fork`) and shares the plan (its caches are pure).
"""

from __future__ import annotations

import os
from collections import OrderedDict

import numpy as np

from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.robot import JACKAL
from dynabarn.sim import Simulation

SHARED_WORLDS = 128
"""Compiled worlds (with their global plans) kept per process for every environment in it."""
_worlds: OrderedDict[tuple[str, int, int], tuple[Simulation, GlobalPlanner]] = OrderedDict()


def shared_world(file: str) -> tuple[Simulation, GlobalPlanner]:
    """A world file compiled once per process and its global plan, which every environment
    of the process forks (`Simulation.fork`) instead of compiling its own: 32 environments
    meeting 60 worlds compile 60, not 1,920. Keyed by the file's size and time too, so a
    procedural world written anew under an old name is compiled anew."""
    st = os.stat(file)
    key = (file, st.st_mtime_ns, st.st_size)
    hit = _worlds.get(key)
    if hit is None:
        sim = Simulation(file)
        cylinders = np.array(sim.world.layout.cylinders).reshape(-1, 3)
        hit = _worlds[key] = (
            sim,
            GlobalPlanner.for_robot(sim.walls, sim.goal, (JACKAL.length, JACKAL.width), cylinders),
        )
        while len(_worlds) > SHARED_WORLDS:
            _worlds.popitem(last=False)
    _worlds.move_to_end(key)
    return hit


def forget_world(file: str) -> None:
    """Drop every compiled version of `file` (a procedural world whose file was removed:
    nobody meets it again, and a world of static cylinders holds some 9 MB)."""
    for key in [k for k in _worlds if k[0] == file]:
        del _worlds[key]
