"""Local goals of many worlds at once: their global plans walked in numpy, not in Python.

A world's local goal is `lookahead` metres along its Dijkstra plan from the robot: the
robot's position, then the next `floor(lookahead / resolution) + 3` cells' centres along
the predecessors (the goal where the plan ends). `GlobalPlanner` walks those cells in
Python and keeps each cell's path; a vector environment of random or learning robots
meets a new cell in every other step and world, and that walk was its largest cost after
the physics and the scan.

Here every world's predecessor field sits in one pool (a slot per world, its indices
shifted to the slot's), so one gather per cell along the plan advances every world at
once. The points are the same cell centres and goals, each world's path is padded by its
last point where the planner's is shorter (segments of length 0: the cumulative sum and
the point found are unchanged), and the rest is `local_goals_in_robot`'s arithmetic:
the same bits (a test compares them over many positions, lookaheads and worlds).
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from dynabarn.perception.map_distance import grid_indices
from dynabarn.planners.global_planner import GlobalPlanner, goals_in_robot_frame, local_goals_in_robot, points_along


class LocalGoalBatch:
    """Local goals in the robot frame for many (planner, pose) pairs in one pass.

    Args:
        capacity: worlds whose plans are kept at once (least recently used dropped first);
            at least the worlds of one call (more: a world that comes back is not copied again).
    """

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self._slots: OrderedDict[int, tuple[int, object]] = OrderedDict()  # id(field) -> (slot, field)
        self._grid: tuple[int, int, float] | None = None  # nx, ny, resolution shared by every slot
        self._next: np.ndarray | None = None  # pooled predecessors; the last entry -1 (so -1 maps to -1)
        self._goals = np.zeros((capacity, 2))
        self._cx = self._cy = np.zeros(0)

    def local_goals_in_robot(self, planners: list[GlobalPlanner], poses: np.ndarray, lookahead: float) -> np.ndarray:
        """(W, 2): `global_planner.local_goals_in_robot(planners, poses, lookahead)`, bit for bit."""
        slots = self._slots_of(planners)
        if slots is None:  # grids of different shapes (not DynaBARN's worlds): the planners' own walk
            return local_goals_in_robot(planners, poses, lookahead)
        nx, ny, res = self._grid
        n_cells = nx * ny
        m = math.floor(lookahead / res) + 3  # the cells a local goal needs (as GlobalPlanner counts)
        # The robot's cell, as `global_planner._cell` finds it (truncation, then the grid's edge).
        i, j = grid_indices(poses[:, 0], poses[:, 1], res, nx, ny)
        base = slots * n_cells
        cells = np.empty((len(poses), m), np.int64)
        at = base + i * nx + j
        for k in range(m):  # one gather per cell along the plan, every world at once
            at = np.take(self._next, at)
            cells[:, k] = at
        ended = cells < 0
        local = np.where(ended, 0, cells - base[:, None])
        paths = np.empty((len(poses), m + 1, 2))
        paths[:, 0] = poses[:, :2]
        paths[:, 1:, 0] = np.where(ended, self._goals[slots, 0][:, None], np.take(self._cx, local % nx))
        paths[:, 1:, 1] = np.where(ended, self._goals[slots, 1][:, None], np.take(self._cy, local // nx))
        # The m-th cell is past the planner's walk when the plan goes on: its path ends one
        # cell earlier, so that row repeats its last point instead.
        cut = ~ended[:, -1]
        paths[cut, -1] = paths[cut, -2]
        return goals_in_robot_frame(points_along(paths, lookahead), poses)

    def _slots_of(self, planners: list[GlobalPlanner]) -> np.ndarray | None:
        """Each planner's slot (its plan copied in when new); None when a grid differs."""
        out = np.empty(len(planners), np.int64)
        in_use: set[int] = set()
        for k, planner in enumerate(planners):
            field = planner.field
            key = id(field)
            kept = self._slots.get(key)
            if kept is None:
                slot = self._assign(planner, in_use)
                if slot is None:
                    return None
            else:
                slot = kept[0]
                self._slots.move_to_end(key)
            in_use.add(slot)
            out[k] = slot
        return out

    def _assign(self, planner: GlobalPlanner, in_use: set[int]) -> int | None:
        field = planner.field
        grid = (field.nx, field.ny, planner.resolution)
        if self._grid is None:
            self._grid = grid
            self._next = np.full(1, -1, np.int32)  # slots added as they are needed (DynaBARN's worlds share one plan)
            self._cx, self._cy = planner.cell_x, planner.cell_y
        elif grid != self._grid:
            return None
        if len(self._slots) < self.capacity:
            slot = len(self._slots)
        else:  # the least recently used world not asked for in this call
            key = next((k for k, (s, _) in self._slots.items() if s not in in_use), None)
            if key is None:
                raise ValueError(f"more worlds in one call than the capacity ({self.capacity})")
            slot = self._slots.pop(key)[0]
        n = field.nx * field.ny
        if len(self._next) < (slot + 1) * n + 1:  # room for twice the slots (up to the capacity)
            grown = np.full(min(self.capacity, 2 * slot + 2) * n + 1, -1, np.int32)
            grown[: len(self._next) - 1] = self._next[:-1]
            self._next = grown
        pred = field.pred_array
        # Shifted into the slot; the goal's and unreachable cells' "none" (< 0) stays -1.
        self._next[slot * n : (slot + 1) * n] = np.where(pred >= 0, pred + np.int32(slot * n), -1)
        self._goals[slot] = planner.goal
        # The field is kept with its slot: its id cannot be reused by another while it is here.
        self._slots[id(field)] = (slot, field)
        return slot
