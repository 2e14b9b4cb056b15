"""The measured difficulty score: deterministic, and it measures what it says."""

import json

import pytest

from dynabarn.mjcf import read_world
from dynabarn.provenance import SHIPPED_WORLDS
from dynabarn.worlds.difficulty import difficulty_scores
from dynabarn.worlds.spec import EndBehavior, Interpolation, WorldSpec
from tests.helpers import obstacle


def _world(*obstacles):
    return WorldSpec(
        name="t",
        world_id=None,
        difficulty="easy",
        obstacles=tuple(obstacles),
        interpolation=Interpolation.LINEAR,
        end_behavior=EndBehavior.LOOP,
    )


def test_known_answers():
    assert difficulty_scores(_world())["corridor_blocked"] == 0.0
    parked = obstacle("obstacle_000", [[0, 0, 0], [1000, 0, 0]])
    s = difficulty_scores(_world(parked))
    assert s["corridor_blocked"] == 1.0 and s["corridor_occupancy"] == 1.0 and s["crossings_per_minute"] == 1.0
    away = obstacle("obstacle_000", [[0, 0, 5], [1000, 0, 5]])
    assert difficulty_scores(_world(away))["corridor_blocked"] == 0.0
    # Crossing the corridor (|y| <= 0.715) at 1 m/s from y = -10 to 10, looping every 20 s:
    crossing = obstacle("obstacle_000", [[0, 0, -10], [20, 0, 10]])
    s = difficulty_scores(_world(crossing))
    assert s["corridor_blocked"] == pytest.approx(2 * 0.715 / 20, abs=0.01)
    assert s["crossings_per_minute"] == 3.0


def test_deterministic_and_stored_in_the_index():
    index = json.loads((SHIPPED_WORLDS / "index.json").read_text())
    for entry in index["worlds"][::60]:
        world = read_world(SHIPPED_WORLDS / entry["file"])
        assert difficulty_scores(world) == entry["measured"] == difficulty_scores(world)


def test_harder_branches_score_higher_on_average():
    index = json.loads((SHIPPED_WORLDS / "index.json").read_text())
    mean = {
        d: sum(w["measured"]["corridor_blocked"] for w in index["worlds"] if w["difficulty"] == d) / 100
        for d in ("easy", "hard")
    }
    assert mean["hard"] > mean["easy"] + 0.1
