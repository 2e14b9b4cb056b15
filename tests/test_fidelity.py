"""Statistical fidelity of `--profiles release2022` against the 2022 release.

Two-sample Kolmogorov-Smirnov statistics D (the largest gap between the two empirical
CDFs) per motion profile, between 600 generated trajectories and the release's 200:
- segment speeds, both put on the release's 0.1 m/s grid (its keyframe times carry only
  two decimals, so its raw speeds are noisy): D must stay below 0.10;
- waypoints per trajectory: D must stay below 0.30 (easy and medium match closely; hard
  is the worst, see README "Paper versus release").
The measured values are printed (pytest -s) and quoted in the README.
"""

import collections

import numpy as np
import pytest
from scipy import stats

from dynabarn.worlds.profiles import get_profile_set
from dynabarn.worlds.trajectory import generate_trajectory

SPEED_D_MAX = 0.10
WAYPOINTS_D_MAX = 0.30


@pytest.fixture(scope="module")
def release_stats(release_json):
    speeds, counts = collections.defaultdict(list), collections.defaultdict(list)
    for plugin in release_json["plugins"].values():
        kf = np.asarray(plugin["keyframes"])
        s = np.hypot(*np.diff(kf[:, 1:], axis=0).T) / np.diff(kf[:, 0])
        speeds[plugin["difficulty"]].extend(np.round(s, 1))
        counts[plugin["difficulty"]].append(len(kf))
    return speeds, counts


@pytest.mark.parametrize("profile_name", ["easy", "medium", "hard"])
def test_release2022_matches_release(release_stats, profile_name):
    speeds, counts = release_stats
    ps = get_profile_set("release2022")
    profile = ps.profile(profile_name)
    rng = np.random.default_rng(np.random.SeedSequence([2022, 7]))
    trajs = [generate_trajectory(rng, profile, scheme=ps.waypoints) for _ in range(600)]
    gen_speeds = np.round(np.concatenate([t.segment_speeds() for t in trajs]), 1)
    gen_counts = [len(t.times) for t in trajs]
    d_speed = stats.ks_2samp(gen_speeds, speeds[profile_name]).statistic
    d_count = stats.ks_2samp(gen_counts, counts[profile_name]).statistic
    print(f"\n{profile_name}: KS D speeds {d_speed:.3f}, waypoints/trajectory {d_count:.3f}")
    assert d_speed < SPEED_D_MAX
    assert d_count < WAYPOINTS_D_MAX
    # Same support: every generated speed is one the release uses for this profile.
    assert set(np.unique(gen_speeds)) <= set(np.unique(speeds[profile_name]))


def test_table1_differs_from_release_where_documented(release_stats):
    """Table I's single hard band (1.0-2.0, continuous) is not the release's hard band."""
    speeds, _ = release_stats
    profile = get_profile_set("table1").profile("hard")
    rng = np.random.default_rng(5)
    s = np.concatenate([generate_trajectory(rng, profile).segment_speeds() for _ in range(300)])
    assert stats.ks_2samp(np.round(s, 1), speeds["hard"]).statistic > 0.3
