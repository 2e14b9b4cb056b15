import pytest

from dynabarn.errors import ProfileError
from dynabarn.worlds.profiles import (
    PROFILE_SETS,
    CountClass,
    Difficulty,
    MotionClass,
    MotionProfile,
    ProfileSet,
    difficulty_of,
    get_profile_set,
)


def test_table1_is_the_papers_table():
    s = get_profile_set("table1")
    (easy,), (hard,) = s.easy_motion, s.hard_motion
    assert (easy.order, easy.speed, easy.std) == ((1, 2), (0.5, 1.0), (0.01, 0.1))
    assert (hard.order, hard.speed, hard.std) == ((3, 4), (1.0, 2.0), (0.1, 0.2))
    assert s.low_count == (5, 9) and s.high_count == (10, 19)


def test_release2022_speed_bands():
    s = get_profile_set("release2022")
    bands = {p.name: p.speed for p in (*s.easy_motion, *s.hard_motion)}
    assert bands == {"easy": (0.5, 1.0), "medium": (1.0, 1.5), "hard": (1.5, 2.0)}
    assert list(s.profile("medium").quantised_speeds()) == [1.0, 1.1, 1.2, 1.3, 1.4]


def test_difficulty_tree_fig2():
    assert difficulty_of(CountClass.LOW, MotionClass.EASY) is Difficulty.EASY
    assert difficulty_of(CountClass.LOW, MotionClass.HARD) is Difficulty.MEDIUM
    assert difficulty_of(CountClass.HIGH, MotionClass.EASY) is Difficulty.MEDIUM
    assert difficulty_of(CountClass.HIGH, MotionClass.HARD) is Difficulty.HARD


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"speed": (1.0, 0.5)}, "min > max"),
        ({"speed": (-0.5, 1.0)}, "below"),
        ({"speed": (0.0, 1.0)}, "positive"),
        ({"order": (0, 2)}, "below 1"),
        ({"order": (3, 2)}, "min > max"),
        ({"std": (0.2, 0.1)}, "min > max"),
        ({"std": (-0.1, 0.1)}, "below"),
        ({"speed_limit": "bounce"}, "unknown speed_limit"),
    ],
)
def test_impossible_profiles_are_rejected(kwargs, message):
    base = {"name": "x", "order": (1, 2), "speed": (0.5, 1.0), "std": (0.01, 0.1)}
    with pytest.raises(ProfileError, match=message):
        MotionProfile(**{**base, **kwargs})


def test_impossible_counts_are_rejected():
    p = PROFILE_SETS["table1"].easy_motion
    with pytest.raises(ProfileError, match=">= 1"):
        ProfileSet("x", p, p, low_count=(0, 3))
    with pytest.raises(ProfileError, match="min > max"):
        ProfileSet("x", p, p, high_count=(12, 10))
    with pytest.raises(ProfileError, match="at least one"):
        ProfileSet("x", (), p)


def test_profile_set_json_round_trip():
    for s in PROFILE_SETS.values():
        assert ProfileSet.from_dict(s.to_dict()) == s


def test_unknown_profile_set_lists_choices():
    with pytest.raises(ProfileError, match="available: release2022, table1"):
        get_profile_set("table2")
