"""The `registered` tracker (velocity from returns registered scan to scan) against known
answers: the registration on point sets moved by a known translation, and the tracker on
MuJoCo scans of a box, a capsule and a cylinder moving past the Jackal's laser."""

from __future__ import annotations

import numpy as np
import pytest

from dynabarn.interfaces import recorded_config
from dynabarn.perception.registered_tracker import RegisteredTracker, RegisteredTrackerConfig
from dynabarn.perception.registration import padded, register
from dynabarn.perception.tracker import ObstacleTracker
from dynabarn.perception.trackers import TRACKERS
from dynabarn.planners.tracking import with_tracker
from tests.laser_scene import Scene

SETTINGS = {"sigma": 0.03, "trim": 0.15, "coarse_trim": 0.6, "prior": 0.01, "iterations": 5}
BOX = {"kind": "box", "half": (0.5, 0.25), "yaw": 0.4}
CAPSULE = {"kind": "capsule", "radius": 0.3, "half_length": 0.6, "yaw": 1.0}
CYLINDER = {"kind": "cylinder", "radius": 0.5}


def _corner(n: int = 30) -> np.ndarray:
    """Returns along two sides of a corner, 2 cm apart, in scan order."""
    side = np.linspace(0.0, 0.6, n // 2)
    return np.concatenate([np.column_stack([0.6 - side, np.zeros_like(side)]), np.column_stack([0 * side, side])])


def _registered(earlier: np.ndarray, current: np.ndarray, guess=(0.0, 0.0)):
    e, e_mask = padded(earlier, np.zeros(len(earlier), dtype=np.int64), np.array([0]))
    c, c_mask = padded(current, np.zeros(len(current), dtype=np.int64), np.array([0]))
    return register(c, c_mask, e, e_mask, np.array([guess], dtype=float), **SETTINGS)


def test_a_corner_moved_by_a_known_translation_is_registered_to_it():
    rng = np.random.default_rng(0)
    earlier = _corner()
    shift = np.array([0.21, -0.13])  # an obstacle at 2.5 m/s for 0.1 s
    current = earlier + shift + rng.normal(0.0, 0.005, earlier.shape)
    found = _registered(earlier, current)  # from no motion at all: the coarse trim finds it
    assert np.abs(found.shift[0] - shift).max() < 0.01
    assert found.matched[0] == len(current)
    assert found.variance[0].max() < 1e-3  # both directions pinned by the two sides


def test_a_flat_side_says_nothing_along_itself_and_its_variance_says_so():
    """The aperture problem: a wall sliding along itself looks the same; the registration
    keeps the guess along it and reports a variance there larger than the prior allows
    (sigma^2 / prior), while across it the shift is exact."""
    side = np.column_stack([np.linspace(0.0, 1.0, 40), np.zeros(40)])
    current = side + np.array([0.0, 0.08])  # moved across itself only
    found = _registered(side, current, guess=(0.05, 0.0))
    assert abs(found.shift[0, 1] - 0.08) < 1e-3
    assert found.variance[0, 0] > 0.5 * SETTINGS["sigma"] ** 2 / SETTINGS["prior"]
    assert found.variance[0, 0] > 1000 * found.variance[0, 1]


def test_point_sets_are_padded_per_group_in_order():
    points = np.arange(12, dtype=float).reshape(6, 2)
    group = np.array([3, 1, 3, 7, 1, 3])
    out, mask = padded(points, group, np.array([3, 7, 9]))
    assert mask.sum(axis=1).tolist() == [3, 1, 0]
    assert out[0, :3].tolist() == [[0, 1], [4, 5], [10, 11]]
    assert out[1, 0].tolist() == [6, 7]


def _velocity_errors(kind: type[ObstacleTracker], shape: dict, reverse_at: int | None = None) -> np.ndarray:
    """Per scan (10 Hz, 2.5 s), the tracked velocity's error [m/s] of one obstacle passing
    the robot at (0, 0) at 1.8 m/s, 2.5-4.5 m away (nan where it is not one track)."""
    scene = Scene([shape])
    tracker = scene.tracker(kind)
    pose, position, velocity = np.zeros(3), np.array([4.0, 2.5]), np.array([0.3, -1.8])
    errors = []
    for i in range(25):
        if i == reverse_at:
            velocity = -velocity
        if i:
            position = position + 0.1 * velocity
        tracks = tracker.update(0.1 * i, scene.scan(position[None], pose), pose)
        errors.append(np.hypot(*(tracks.velocities[0] - velocity)) if len(tracks) == 1 else np.nan)
    return np.array(errors)


@pytest.mark.parametrize("shape", [BOX, CAPSULE], ids=["box", "capsule"])
def test_a_box_or_capsule_passing_by_gets_its_velocity_from_the_registration(shape):
    """The circle of the known radius round a box or a capsule moves on the outline as the
    view turns, and its differences are the fitted-centre tracker's velocity error; the
    registration's is a tenth of it (measured: 0.007 against 0.066 m/s for the box, 0.006
    against 0.107 for the capsule)."""
    registered = _velocity_errors(RegisteredTracker, shape)[5:]
    kalman = _velocity_errors(ObstacleTracker, shape)[5:]
    assert np.isfinite(registered).all()
    assert np.median(registered) < 0.03
    assert np.median(registered) < 0.3 * np.median(kalman)


def test_a_cylinder_is_tracked_as_well_as_by_the_circle_tracker():
    registered = _velocity_errors(RegisteredTracker, CYLINDER)[5:]
    assert np.median(registered) < 0.03 and registered.max() < 0.1


def test_a_box_that_reverses_is_followed_within_a_scan_or_two():
    """Obstacles of the `integer` waypoints turn sharply at a waypoint. In the five scans
    after a box reverses at 1.8 m/s, the registered velocity is at most 0.25 m/s off
    (measured), the fitted centre's up to 1.4 m/s."""
    registered = _velocity_errors(RegisteredTracker, BOX, reverse_at=10)[10:16]
    kalman = _velocity_errors(ObstacleTracker, BOX, reverse_at=10)[10:16]
    assert registered.max() < 0.4
    assert registered.max() < 0.5 * kalman.max()


def test_registered_is_a_tracker_kind_with_its_own_recorded_settings():
    assert TRACKERS.get_item("registered") is RegisteredTracker
    config = with_tracker({"tracker.kind": "registered", "tracker.registration_trim": 0.1}, "p")["tracker"]
    assert type(config) is RegisteredTrackerConfig and config.registration_trim == 0.1
    recorded = recorded_config(config)
    assert recorded["kind"] == "registered" and recorded["registration_trim"] == 0.1
    with pytest.raises(TypeError, match="registration_trim"):
        with_tracker({"tracker.registration_trim": 0.1}, "p")  # not the circle tracker's
