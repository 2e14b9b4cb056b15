"""Known answers for the skill interval (docs/concepts/statistics.md): it never leaves
[-1, 1], never has zero width, and agrees with textbook values where they exist."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from dynabarn.bench.stats import (
    MIN_WORLDS,
    design_effect,
    paired_difference_interval,
    skill_over_floor,
    skill_text,
    tango_interval,
)
from dynabarn.bench.summary import FLOOR, format_table, summarise


def _rows(planner: str, outcomes: list[list[int]]) -> list[dict]:
    return [
        {
            "planner": planner,
            "world": f"w{w}",
            "seed": s,
            "outcome": "success" if o else "collision",
            "difficulty": "hard",
        }
        for w, trials in enumerate(outcomes)
        for s, o in enumerate(trials)
    ]


def test_all_success_against_all_failure_on_three_worlds():
    """Three worlds of ten trials where the planner always wins: the point is +1, the
    interval reaches +1 and has width; three worlds cannot exclude zero (McNemar's exact test
    on three discordant pairs: p = 0.25), so the lower bound is below it."""
    r = skill_over_floor(_rows("p", [[1] * 10] * 3), _rows(FLOOR, [[0] * 10] * 3))
    assert r["skill"] == 1.0 and r["skill_hi"] == 1.0
    assert -0.2 < r["skill_lo"] < 0.0
    assert r["skill_worlds"] == 3
    # The same on 60 worlds excludes zero by far.
    r = skill_over_floor(_rows("p", [[1] * 10] * 60), _rows(FLOOR, [[0] * 10] * 60))
    assert 0.85 < r["skill_lo"] < 1.0 == r["skill_hi"]
    # And the mirror image.
    r = skill_over_floor(_rows("p", [[0] * 10] * 3), _rows(FLOOR, [[1] * 10] * 3))
    assert r["skill"] == -1.0 == r["skill_lo"] and 0.0 < r["skill_hi"] < 0.2


@pytest.mark.parametrize("p", [0.0, 0.3, 0.5, 1.0])
def test_identical_planners_have_an_interval_around_zero(p):
    """Two planners with the same outcome on every episode: skill 0, an interval about zero
    of positive width (not [+0.00, +0.00]), symmetric because nothing favours either."""
    trials = [[int(k < p * 10) for k in range(10)] for _ in range(4)]
    r = skill_over_floor(_rows("p", trials), _rows(FLOOR, trials))
    assert r["skill"] == 0.0
    assert r["skill_lo"] < -0.05 and r["skill_hi"] > 0.05
    assert r["skill_lo"] == pytest.approx(-r["skill_hi"], abs=1e-9)


def test_bounds_never_leave_minus_one_to_one_and_never_collapse():
    rng = np.random.default_rng(0)
    for _ in range(300):
        worlds = int(rng.integers(1, 8))
        trials = int(rng.integers(1, 11))
        a = rng.integers(0, 2, size=(worlds, trials)).tolist()
        b = rng.integers(0, 2, size=(worlds, trials)).tolist()
        r = skill_over_floor(_rows("p", a), _rows(FLOOR, b))
        assert -1.0 <= r["skill_lo"] <= r["skill"] <= r["skill_hi"] <= 1.0
        assert r["skill_hi"] - r["skill_lo"] > 0.01


def test_tango_matches_the_score_test_it_inverts():
    """At each bound the score statistic equals +-1.96, and the nuisance parameter the
    closed form gives is the constrained maximum likelihood (found here numerically)."""
    from dynabarn.bench.stats import Z95, _tango_statistic

    b, c, n = 12, 4, 40
    lo, hi = tango_interval(b, c, n)
    assert float(_tango_statistic(np.array(lo), b, c, n)) == pytest.approx(Z95, abs=1e-6)
    assert float(_tango_statistic(np.array(hi), b, c, n)) == pytest.approx(-Z95, abs=1e-6)
    # McNemar's score test is the statistic at delta = 0: (b - c) / sqrt(b + c).
    assert float(_tango_statistic(np.array(0.0), b, c, n)) == pytest.approx((b - c) / math.sqrt(b + c))
    delta = 0.1
    a = n - b - c
    w = -b - c + (2 * n - b + c) * delta
    closed = (math.sqrt(w * w + 8 * n * c * delta * (1 - delta)) - w) / (4 * n)

    def minus_log_likelihood(p21):
        return -(b * math.log(p21 + delta) + c * math.log(p21) + a * math.log(1 - 2 * p21 - delta))

    found = minimize_scalar(minus_log_likelihood, bounds=(1e-9, (1 - delta) / 2 - 1e-9), method="bounded").x
    assert closed == pytest.approx(found, abs=1e-6)


def test_design_effect_counts_each_world_once_when_trials_are_alike():
    alike = [[1.0] * 10, [0.0] * 10, [1.0] * 10, [0.0] * 10]
    assert design_effect(alike) == pytest.approx(10.0, rel=0.05)
    # Trials spread evenly across worlds: no clustering to correct for.
    spread = [[1.0, 0.0] * 5 for _ in range(4)]
    assert design_effect(spread) == 1.0
    # Nothing varies: each world counts once.
    assert design_effect([[1.0] * 10] * 3) == 10.0
    # One world: its trials are all there is, and they count as one.
    estimate, lo, hi = paired_difference_interval([[1.0] * 10])
    assert estimate == 1.0 and lo < 0 and hi == 1.0


def test_tables_mark_a_skill_on_few_worlds_and_print_no_nan():
    rows = _rows("p", [[0] * 2] * 3) + _rows(FLOOR, [[0] * 2] * 3)
    table = format_table(summarise(rows))
    assert "\u2020" in table and f"fewer than {MIN_WORLDS} worlds" in table
    assert "nan" not in table
    many = _rows("p", [[1, 0]] * MIN_WORLDS) + _rows(FLOOR, [[0, 0]] * MIN_WORLDS)
    s = next(s for s in summarise(many) if s["planner"] == "p" and s["difficulty"] == "all")
    assert "\u2020" not in skill_text(s) and s["skill_worlds"] == MIN_WORLDS
