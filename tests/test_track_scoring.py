"""The tracking scorer's identity switches, by both rules, on tracks with known answers."""

from types import SimpleNamespace

import numpy as np

from dynabarn.sim.track_scoring import TRACKING_FIELDS, TrackScorer


def _tracks(ids, positions):
    positions = np.asarray(positions, dtype=float).reshape(-1, 2)
    return SimpleNamespace(
        ids=np.asarray(ids, dtype=np.int64), positions=positions, velocities=np.zeros_like(positions)
    )


def _run(ticks, obstacles):
    scorer = TrackScorer(len(obstacles))
    truth = np.asarray(obstacles, dtype=float)
    for ids, positions in ticks:
        scorer.add(_tracks(ids, positions), truth, np.zeros_like(truth), np.ones(len(truth), dtype=bool))
    return scorer.summary()


def test_two_tracks_near_one_obstacle_trading_the_nearer_place_switch_every_tick_afresh_and_never_by_clear_mot():
    # Track 1 and track 2 are both within the match distance of the obstacle at the origin,
    # and take turns being the nearer: matched afresh each tick, the obstacle changes track
    # every tick; CLEAR-MOT keeps its first track while it stays within the match distance.
    near, far = (0.2, 0.0), (-0.6, 0.0)
    ticks = [([1, 2], [near, far]) if t % 2 == 0 else ([1, 2], [far, near]) for t in range(10)]
    s = _run(ticks, [(0.0, 0.0)])
    assert s["id_switches"] == 9
    assert s["id_switches_mot"] == 0
    assert set(s) == set(TRACKING_FIELDS)


def test_a_track_that_leaves_its_obstacle_for_another_to_take_over_is_one_switch_by_both_rules():
    ticks = [([1, 2], [(0.1, 0.0), (3.0, 3.0)])] * 3 + [([1, 2], [(1.5, 0.0), (0.1, 0.0)])] * 3
    s = _run(ticks, [(0.0, 0.0)])
    assert s["id_switches"] == 1
    assert s["id_switches_mot"] == 1


def test_an_obstacle_lost_and_found_again_by_its_own_track_is_no_switch_and_by_a_new_one_is_one():
    own = [([1], [(0.1, 0.0)]), ([], []), ([1], [(0.1, 0.0)])]
    s = _run(own, [(0.0, 0.0)])
    assert s["id_switches"] == 0 and s["id_switches_mot"] == 0
    reborn = [([1], [(0.1, 0.0)]), ([7], [(5.0, 5.0)]), ([8], [(0.1, 0.0)])]
    s = _run(reborn, [(0.0, 0.0)])
    assert s["id_switches"] == 1 and s["id_switches_mot"] == 1


def test_two_tracks_swapping_places_within_the_match_distance_switch_afresh_and_are_kept_by_clear_mot():
    # Obstacles 0.4 m apart; from the fourth tick on the two tracks trade places. Matched
    # afresh, each obstacle changes track once; CLEAR-MOT keeps each old pair, still within
    # the match distance (its known blind spot: a swap inside the distance is not one).
    a, b = (-0.2, 0.0), (0.2, 0.0)
    before = ([1, 2], [(-0.2, 0.05), (0.2, 0.05)])
    after = ([1, 2], [(0.2, 0.05), (-0.2, 0.05)])
    s = _run([before] * 3 + [after] * 3, [a, b])
    assert s["id_switches"] == 2
    assert s["id_switches_mot"] == 0
