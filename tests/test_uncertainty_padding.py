"""Planning against the tracker's uncertainty (issue 57, part 2): every planner that predicts
tracks (`predictive`, `dwa` and `teb` with `include_dynamic_obstacles`) keeps clear of each
track's radius grown by its predicted position's standard deviation (`Tracks.padded_sizes`);
known answers from hand-made tracks."""

from __future__ import annotations

import numpy as np
import pytest

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import recorded_config
from dynabarn.perception import Tracks
from dynabarn.planners import get_planner
from dynabarn.planners.tracking import distance_to_tracks


def _track(position=(2.0, 0.0), velocity=(0.0, 0.0), size=0.5, position_std=0.2, velocity_std=0.0) -> Tracks:
    """One track at time 10 s whose predicted position's std is `position_std` now and grows
    by `velocity_std` per second (no cross covariance)."""
    one = np.ones((1, 2))
    return Tracks(
        time=10.0,
        ids=np.array([7]),
        positions=np.array([position], dtype=float),
        velocities=np.array([velocity], dtype=float),
        sizes=np.array([size]),
        position_var=position_std**2 * one,
        velocity_var=velocity_std**2 * one,
        position_velocity_cov=0.0 * one,
        age=np.array([3.0]),
        last_seen=np.array([10.0]),
    )


def test_a_tracks_radius_grows_by_its_position_std_up_to_the_cap():
    tracks = _track(position_std=0.2, velocity_std=1.0)
    times = np.array([10.0, 10.1, 11.0])
    # std(t) = sqrt(0.04 + t^2): 0.2, 0.2236, 1.0198 (capped at 0.3)
    expected = 0.5 + np.array([[0.2], [np.sqrt(0.05)], [0.3]])
    assert np.allclose(tracks.padded_sizes(times, 1.0, 0.3), expected, atol=1e-12)
    assert np.allclose(tracks.padded_sizes(10.0, 0.5, 0.3), [0.6], atol=1e-12)
    plain = tracks.padded_sizes(times, 0.0, 0.3)
    assert plain.shape == (3, 1) and (plain == 0.5).all() and plain.flags.writeable


def test_dwa_keeps_clear_of_a_tracks_uncertainty_only_when_asked():
    xy = np.zeros((1, 3, 2))  # one rollout standing at the origin for three steps
    times = np.array([0.0, 0.1, 0.2])
    clearances = {}
    for sigmas in (0.0, 1.0, 3.0):
        planner = get_planner("dwa", include_dynamic_obstacles=True, uncertainty_sigmas=sigmas)
        planner._tracks = _track(position_std=0.2)
        clearances[sigmas] = float(planner._moving_clearance(xy, 10.0, times)[0])
    # 2 m to the centre, radius 0.5; + 1 std (0.2); + 3 std capped at max_padding 0.3
    assert clearances == pytest.approx({0.0: 1.5, 1.0: 1.3, 3.0: 1.2}, abs=1e-12)


def test_dwa_refuses_a_rollout_that_passes_inside_a_young_tracks_uncertainty():
    xy = np.stack([np.column_stack([np.zeros(5), np.linspace(0.0, 0.4, 5)])])  # 0.4 m along y
    times = np.arange(5) * 0.1
    young = _track(position=(0.9, 0.0), position_std=0.02, velocity_std=2.0)  # its speed unknown
    plain = get_planner("dwa", include_dynamic_obstacles=True)
    padded = get_planner("dwa", include_dynamic_obstacles=True, uncertainty_sigmas=1.0)
    for planner in (plain, padded):
        planner._tracks = young
    r = plain.cfg.collision_radius
    assert plain._moving_clearance(xy, 10.0, times)[0] == pytest.approx(0.4, abs=1e-12)  # >= r: admissible
    # nearest 0.2 s on: 0.922 m from the centre, the radius grown by the cap (std 0.4 > 0.3)
    assert padded._moving_clearance(xy, 10.0, times)[0] == pytest.approx(np.hypot(0.9, 0.2) - 0.5 - 0.3, abs=1e-12)
    assert padded._moving_clearance(xy, 10.0, times)[0] < r


def test_teb_keeps_its_band_clear_of_the_grown_radius_at_each_poses_time():
    moving = _track(position_std=0.0, velocity_std=0.5)
    x, y = np.zeros((1, 3)), np.zeros((1, 3))  # three inner poses at the origin
    ahead = np.array([[0.2, 0.4, 0.6]])  # seconds from now
    plain = distance_to_tracks(x, y, ahead, moving, get_planner("teb").cfg)
    padded = distance_to_tracks(x, y, ahead, moving, get_planner("teb", uncertainty_sigmas=2.0).cfg)
    assert np.allclose(plain, 1.5, atol=1e-12)
    # 2 x 0.5 m/s x t, at most 0.3: 0.2, 0.3, 0.3
    assert np.allclose(plain - padded, [[0.2, 0.3, 0.3]], atol=1e-12)
    assert distance_to_tracks(x, y, ahead, Tracks.empty(10.0), get_planner("teb").cfg).tolist() == [[np.inf] * 3]


def test_a_moving_track_is_met_where_it_will_be():
    moving = _track(position=(2.0, 0.0), velocity=(-1.0, 0.0), position_std=0.0)  # 1 m/s towards the origin
    x, y = np.zeros(3), np.zeros(3)
    assert np.allclose(distance_to_tracks(x, y, np.array([0.0, 0.5, 1.0]), moving, get_planner("teb").cfg),
                       [1.5, 1.0, 0.5], atol=1e-12)  # fmt: skip


@pytest.mark.parametrize("name", ["dwa", "teb"])
def test_the_padding_is_recorded_only_when_on_and_checked(name):
    assert "uncertainty_sigmas" not in recorded_config(get_planner(name).cfg)  # earlier results as they were
    on = recorded_config(get_planner(name, uncertainty_sigmas=1.0, max_padding=0.2).cfg)
    assert (on["uncertainty_sigmas"], on["max_padding"]) == (1.0, 0.2)
    with pytest.raises(DynabarnError, match="uncertainty_sigmas"):
        get_planner(name, uncertainty_sigmas=-1.0)
