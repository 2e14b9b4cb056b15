"""The `shaped` tracker against known answers: scenes built with `mujoco.MjSpec` (boxes,
capsules, cylinders on mocap bodies, a standing cylinder of the known map) and scanned by
MuJoCo's own ray casting from the Jackal's laser, with its noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dynabarn.perception.shape_fit import fit_headings
from dynabarn.perception.shaped_tracker import SEEN_EXTENT_STD, ShapeTracker
from dynabarn.perception.tracker import ObstacleTracker, TrackerConfig
from dynabarn.perception.trackers import TRACKERS
from dynabarn.perception.tracks import Tracks
from tests.laser_scene import Scene, pose_looking_at


def _heading_error(estimate: float, truth: float) -> float:
    """Difference of two rectangle headings (the same a right angle on) [rad]."""
    return abs((estimate - truth + math.pi / 4) % (math.pi / 2) - math.pi / 4)


def test_the_shaped_tracker_is_registered_and_the_circle_tracker_stays_the_default():
    assert TRACKERS.get_item("shaped") is ShapeTracker
    assert TrackerConfig().kind == "kalman"


def test_each_tracker_takes_its_own_settings_and_records_them_as_before():
    """`tracker.*` keys are checked against the `Config` of the kind they name: the
    outlines' settings are the shaped tracker's, refused for the circle tracker; what is
    recorded is what was recorded before the split (the golden set's bytes)."""
    from dynabarn.interfaces import recorded_config
    from dynabarn.perception.shaped_tracker import ShapeTrackerConfig
    from dynabarn.planners.tracking import with_tracker

    shaped = with_tracker({"tracker.kind": "shaped", "tracker.shape.extent_sigmas": 2.0}, "p")["tracker"]
    assert type(shaped) is ShapeTrackerConfig and shaped.shape.extent_sigmas == 2.0
    with pytest.raises(TypeError, match=r"unknown p tracker parameter.*shape"):
        with_tracker({"tracker.shape.extent_sigmas": 2.0}, "p")
    kalman = with_tracker({"tracker.gate": 0.5}, "p")["tracker"]
    assert type(kalman) is TrackerConfig
    assert list(recorded_config(kalman)) == [
        "accel_std", "measurement_std", "birth_speed_std", "gate", "max_coast", "max_unseen_in_view", "detector",
    ]  # fmt: skip
    keys = list(recorded_config(shaped))
    assert keys[0] == "kind" and keys[-1] == "shape"


def test_a_box_seen_at_a_corner_gives_its_centre_extent_and_heading():
    # Seen across a corner (two sides facing the laser), one scan tells a box whole.
    centre, half, yaw = np.array([2.0, 1.0]), (0.5, 0.25), 0.4
    scene = Scene([{"kind": "box", "half": half, "yaw": yaw}])
    for bearing in yaw + np.array([0.25, 0.75, 1.25, 1.75]) * math.pi:  # the four corners
        tracker = scene.tracker()
        pose = pose_looking_at(centre, bearing, 4.0)
        tracks = tracker.update(0.0, scene.scan(centre[None], pose), pose)
        assert len(tracks) == 1
        assert np.hypot(*(tracks.positions[0] - centre)) < 0.03
        assert _heading_error(tracks.headings[0], yaw) < math.radians(2.0)
        assert sorted(tracks.half_sizes[0]) == pytest.approx(sorted(half), abs=0.03)


def test_a_box_seen_from_every_side_gives_its_centre_extent_and_heading():
    # Face on, a box's depth is hidden: the robot goes round it (8 views, one track).
    centre, half, yaw = np.array([-1.0, 3.0]), (0.55, 0.3), 1.1
    scene = Scene([{"kind": "box", "half": half, "yaw": yaw}])
    tracker = scene.tracker()
    for k, bearing in enumerate(np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)):
        pose = pose_looking_at(centre, bearing, 3.5)
        tracks = tracker.update(0.1 * k, scene.scan(centre[None], pose), pose)
        assert len(tracks) == 1 and tracks.ids[0] == 0
    assert np.hypot(*(tracks.positions[0] - centre)) < 0.03
    assert _heading_error(tracks.headings[0], yaw) < math.radians(2.0)
    assert sorted(tracks.half_sizes[0]) == pytest.approx(sorted(half), abs=0.03)
    assert np.all(tracks.half_size_std[0] <= SEEN_EXTENT_STD)  # every extent seen whole


def test_a_box_seen_face_on_is_placed_behind_its_face_with_an_uncertain_depth():
    centre, half, yaw = np.array([0.0, 0.0]), (0.5, 0.2), 0.0
    scene = Scene([{"kind": "box", "half": half, "yaw": yaw}])
    tracker = scene.tracker()
    pose = pose_looking_at(centre, -math.pi / 2, 4.0)  # straight at the long side
    tracks = tracker.update(0.0, scene.scan(centre[None], pose), pose)
    across = tracks.positions[0] - centre
    assert abs(across[0]) < 0.03  # along the face: exact
    # In depth: the near face is seen, the depth is the prior's (0.4 for the true 0.2).
    assert across[1] == pytest.approx(0.4 - 0.2, abs=0.03)
    assert tracks.half_size_std[0].max() > 0.1  # and the tracker says it does not know it


CAPSULE = {"kind": "capsule", "yaw": 0.7, "radius": 0.35, "half_length": 0.7}


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_capsule_passed_by_is_tracked_by_its_outline_not_by_a_circle(side):
    centre, yaw = np.array([1.0, -2.0]), CAPSULE["yaw"]
    scene = Scene([CAPSULE])
    shaped, circles = scene.tracker(), scene.tracker(ObstacleTracker)
    for k, off_axis in enumerate(np.linspace(0.6, math.pi - 0.6, 12)):  # from one end to the other
        pose = pose_looking_at(centre, yaw + side * off_axis, 3.0)
        scan = scene.scan(centre[None], pose)
        tracks, circle_tracks = shaped.update(0.1 * k, scan, pose), circles.update(0.1 * k, scan, pose)
    error = np.hypot(*(tracks.positions[0] - centre))
    assert error < 0.1  # its rounded ends never show their whole width: the prior's (0.4 for 0.35)
    assert error < 0.5 * np.hypot(*(circle_tracks.positions - centre).T).min()
    assert _heading_error(tracks.headings[0], yaw) < math.radians(2.0)
    # Its covering circles hold the capsule's ends.
    cover = tracks.covering_circles()
    axis = np.array([math.cos(yaw), math.sin(yaw)])
    reach = CAPSULE["half_length"] + CAPSULE["radius"]
    for end in (centre + reach * axis, centre - reach * axis):
        assert (np.hypot(*(cover.positions - end).T) <= cover.sizes + 0.02).any()


@pytest.mark.parametrize("end", [0.0, math.pi])
def test_a_capsule_seen_end_on_is_placed_across_and_says_its_length_is_unknown(end):
    centre, yaw = np.array([1.0, -2.0]), CAPSULE["yaw"]
    scene = Scene([CAPSULE])
    tracker = scene.tracker()
    for k in range(4):
        pose = pose_looking_at(centre, yaw + end + 0.1 * k, 3.0)
        tracks = tracker.update(0.1 * k, scene.scan(centre[None], pose), pose)
    axis = np.array([math.cos(yaw), math.sin(yaw)])
    error = tracks.positions[0] - centre
    assert abs(error @ np.array([-axis[1], axis[0]])) < 0.08  # across the axis: seen
    # Along it the length is hidden: the centre is the prior's depth behind the cap, and the
    # tracker says how little it knows of that extent.
    hidden = CAPSULE["half_length"] + CAPSULE["radius"] - tracker.cfg.shape.prior_half
    assert abs(error @ axis) < hidden + 0.05
    along = int(abs(math.cos(tracks.headings[0] - yaw)) < abs(math.sin(tracks.headings[0] - yaw)))
    assert tracks.half_size_std[0, along] > 0.15


def test_a_cylinder_keeps_the_circle_trackers_precision():
    centre = np.array([3.0, 0.5])
    scene = Scene([{"kind": "cylinder", "radius": 0.5}])
    tracker = scene.tracker()
    for k in range(4):
        pose = pose_looking_at(centre, 0.4 * k, 5.0)
        tracks = tracker.update(0.1 * k, scene.scan(centre[None], pose), pose)
    assert np.hypot(*(tracks.positions[0] - centre)) < 0.005
    assert tracks.half_sizes[0] == pytest.approx([0.5, 0.5])
    assert len(tracks.covering_circles()) == 1


def test_two_obstacles_passing_close_keep_their_identities():
    # A box and a cylinder cross 1.2 m apart (centres), each at 1.5 m/s, seen from the side.
    scene = Scene([{"kind": "box", "half": (0.4, 0.3), "yaw": 0.2}, {"kind": "cylinder", "radius": 0.5}])
    tracker = scene.tracker()
    pose = np.array([0.0, -5.0, math.pi / 2])
    identity = None
    for k in range(31):
        t = 0.1 * k
        positions = np.array([[-2.25 + 1.5 * t, 0.6], [2.25 - 1.5 * t, -0.6]])
        tracks = tracker.update(t, scene.scan(positions, pose), pose)
        d = np.hypot(*(tracks.positions[:, None] - positions[None]).transpose(2, 0, 1))
        assert d.min(axis=0).max() < 0.5  # both tracked throughout
        nearest = tuple(int(tracks.ids[j]) for j in d.argmin(axis=0))
        identity = identity or nearest
        assert nearest == identity
    assert len(set(identity)) == 2


def test_a_track_hidden_behind_a_standing_cylinder_for_a_second_comes_back_with_its_identity():
    # A box crosses behind a standing cylinder of the known map at 1.2 m/s: about a second
    # with no return from it.
    standing = np.array([[0.0, 1.0, 0.5]])
    scene = Scene([{"kind": "box", "half": (0.3, 0.2), "yaw": 0.0}], standing)
    tracker = scene.tracker()
    pose = np.array([0.0, -2.0, math.pi / 2])
    seen_ids, hidden, longest = set(), 0, 0
    for k in range(40):
        t = 0.1 * k
        position = np.array([[-2.4 + 1.2 * t, 3.0]])
        tracks = tracker.update(t, scene.scan(position, pose), pose)
        hidden = 0 if len(tracker.detections) else hidden + 1
        longest = max(longest, hidden)
        near = np.hypot(*(tracks.positions - position[0]).T) < 0.3 if len(tracks) else np.zeros(0, bool)
        seen_ids |= set(tracks.ids[near].tolist())
    assert 9 <= longest <= 12  # a second (0.9-1.2 s) without a return from it
    assert len(tracks) == 1 and np.hypot(*(tracks.positions[0] - position[0])) < 0.05
    assert seen_ids == {0}  # one track before, behind and after: no new identity


def test_outlines_fit_headings_of_sides_and_call_arcs_round():
    x = np.linspace(-0.5, 0.5, 30)
    yaw = 0.3
    side = np.column_stack([x * math.cos(yaw), x * math.sin(yaw)])
    arc = 0.5 * np.column_stack([np.cos(np.linspace(-1, 1, 30)), np.sin(np.linspace(-1, 1, 30))])
    shapes = fit_headings(np.concatenate([side, arc + 5.0]), np.repeat([0, 1], 30))
    assert _heading_error(shapes.headings[0], yaw) < math.radians(0.5)
    assert shapes.straightness[0] > 0.9 > 0.5 > shapes.straightness[1]


def test_covering_circles_leave_circle_tracks_alone():
    tracks = Tracks(0.0, np.array([3]), np.zeros((1, 2)), np.ones((1, 2)), np.array([0.5]), *(np.zeros((1, 2)),) * 3,
                    np.zeros(1), np.zeros(1))  # fmt: skip
    assert tracks.covering_circles() is tracks
