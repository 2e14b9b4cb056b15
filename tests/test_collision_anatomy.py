"""`benchmarks/collision_anatomy.py`'s classes, from hand-made ticks with known answers: what
the tracker knew of the obstacle that hit in the last second, and where it came from."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from dynabarn.perception import Tracks

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from collision_anatomy import classify
from tracker_tables import anatomy_table


def _tracks(time: float, positions, velocities) -> Tracks:
    n = len(positions)
    z = np.zeros((n, 2))
    return Tracks(
        time, np.arange(n), np.array(positions, float).reshape(n, 2), np.array(velocities, float).reshape(n, 2),
        np.full(n, 0.5), z, z, z, np.ones(n), np.full(n, time),
    )  # fmt: skip


def _ticks(track_of, obstacle_at=(1.0, 0.0), heading=0.0, speed=2.0):
    """Eleven ticks 0.1 s apart: obstacle 0 moving along -x at `speed` to end at
    `obstacle_at`, obstacle 1 far away; the robot at the origin facing `heading`;
    `track_of(k, truth)` gives tick k's tracks."""
    ticks = []
    for k in range(11):
        t = 0.1 * k
        hit = np.array(obstacle_at) + np.array([speed * (1.0 - t), 0.0])
        truth = np.array([hit, [20.0, 20.0]])
        ticks.append((t, truth, track_of(k, truth), np.array([0.0, 0.0, heading])))
    return ticks


def test_a_well_tracked_obstacle_from_the_front():
    ticks = _ticks(lambda k, truth: _tracks(0.1 * k, [truth[0]], [(-2.0, 0.0)]))
    assert classify(ticks, 0) == ("tracked", "front")


def test_never_matched_is_untracked_and_its_bearing_says_behind():
    ticks = _ticks(lambda k, truth: _tracks(0.1 * k, [(20.0, 20.0)], [(0.0, 0.0)]), heading=np.pi)
    assert classify(ticks, 0) == ("untracked", "behind")


def test_seen_then_dropped_is_lost_and_at_130_degrees_is_the_side():
    def track_of(k, truth):
        return _tracks(0.1 * k, [truth[0]] if k < 8 else [(20.0, 20.0)], [(-2.0, 0.0)])

    assert classify(_ticks(track_of, heading=np.radians(130.0)), 0) == ("lost", "side")


@pytest.mark.parametrize(
    ("offset", "velocity", "kind"),
    [((0.6, 0.0), (-2.0, 0.0), "centre off"), ((0.1, 0.0), (0.0, 0.0), "velocity off")],
)
def test_a_centre_or_a_velocity_far_off_is_named(offset, velocity, kind):
    ticks = _ticks(lambda k, truth: _tracks(0.1 * k, [truth[0] + np.array(offset)], [velocity]))
    assert classify(ticks, 0)[0] == kind


def test_the_table_counts_each_class_and_what_the_true_state_survived():
    record = {
        "episodes": [
            {"world": 200, "oracle_present": "success", "kind": "untracked", "side": "behind"},
            {"world": 201, "oracle_present": "collision", "kind": "untracked", "side": "behind"},
            {"world": 202, "oracle_present": "success", "kind": "tracked", "side": "front"},
            {"world": 203, "oracle_present": "success", "kind": "-", "side": "success"},
        ]
    }
    table = anatomy_table(record).splitlines()
    assert table[2 + 0] == "| untracked | 0 (0) | 0 (0) | 2 (1) | 2 (1) |"
    assert table[2 + 4] == "| tracked | 1 (1) | 0 (0) | 0 (0) | 1 (1) |"
    assert table[-1] == "| every collision | 1 (1) | 0 (0) | 2 (1) | 3 (2) |"
    assert anatomy_table(None).startswith("(no record")
