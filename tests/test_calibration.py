"""Difficulty calibrated on the ladder (issue 43, item 4): the fit and its scores on known
answers, the shipped calibration, and `dynabarn-worlds stats --predict`."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dynabarn.bench.calibration import FEATURES, RUNGS, auc, fit_logistic, predict, read_calibration
from dynabarn.cli import worlds_main
from dynabarn.mjcf import read_world
from dynabarn.worlds.difficulty import calibration_features
from dynabarn.worldset import resolve_world


def test_the_fit_recovers_known_coefficients():
    rng = np.random.default_rng(43)
    X = rng.normal(size=(4000, 3))
    beta = np.array([0.5, -1.5, 0.8, 0.0])
    trials = np.full(len(X), 10.0)
    p = 1.0 / (1.0 + np.exp(-(beta[0] + X @ beta[1:])))
    successes = rng.binomial(10, p).astype(float)
    fitted = fit_logistic(X, successes, trials, ridge=1e-6)
    assert np.allclose(fitted, beta, atol=0.05)


def test_auc_known_values():
    won = np.array([True, True, False, False])
    assert auc(np.array([0.9, 0.8, 0.2, 0.1]), won) == 1.0
    assert auc(np.array([0.1, 0.2, 0.8, 0.9]), won) == 0.0
    assert auc(np.array([0.5, 0.5, 0.5, 0.5]), won) == 0.5
    assert math.isnan(auc(np.array([0.5, 0.6]), np.array([True, True])))


def test_features_know_an_empty_corridor_from_a_crowded_one():
    quiet, crowded = (calibration_features(read_world(resolve_world(i))) for i in (0, 250))
    assert set(FEATURES) - {"slack"} <= set(quiet)
    assert crowded["near_density"] > quiet["near_density"] and crowded["crossing_speed"] > quiet["crossing_speed"]
    assert quiet["static_blocked"] == crowded["static_blocked"] == 0.0


def test_the_shipped_calibration_predicts_every_rung_and_ranks_harder_worlds_lower():
    calibration = read_calibration()
    assert set(calibration["rungs"]) <= set(RUNGS) and "straight" in calibration["rungs"]
    for fit in calibration["rungs"].values():
        assert len(fit["coef"]) == len(FEATURES) and fit["held_back"] >= 5
        assert -1.0 <= fit["spearman"] <= 1.0 and 0.0 <= fit["auc"] <= 1.0
    floor = calibration["rungs"]["straight"]
    quiet, crowded = (calibration_features(read_world(resolve_world(i))) for i in (0, 250))
    assert predict(floor, crowded) < predict(floor, quiet)


def test_stats_predicts_each_worlds_success(capsys):
    assert worlds_main(["stats", "paper60", "--worlds", "0,200", "--predict", "dwa"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[2:]]
    assert [r[1] for r in rows] == ["0", "200"] and all(0.0 <= float(r[3]) <= 1.0 for r in rows)


@pytest.mark.parametrize("rung", ["oracle", "nonsense"])
def test_an_uncalibrated_rung_is_one_line_and_exit_2(rung, capsys):
    assert worlds_main(["stats", "paper60", "--worlds", "0", "--predict", rung]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "calibrated rung" in err
