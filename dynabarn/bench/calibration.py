"""Difficulty calibrated on the whole ladder: each rung's success predicted from what a
world's schedules, static geometry and certificate say (issue 43).

For every rung (the floor, DWA and TEB with and without predictions, `predictive`, `dagger`,
`oracle_present`) a binomial logistic regression (ridge, fitted by iteratively reweighted
least squares in numpy) maps a world's `worlds.difficulty.calibration_features` and its
certificate's slack to the chance that an episode there succeeds. Worlds are split by
their file's sha256 (a fifth held back, never fitted); on the held-back worlds each rung
reports Spearman's rank correlation between the predicted difficulty (one minus the
predicted success) and the actual success per world (negative: it ranks them), beside
the strongest any measure could reach against rates that tie (`spearman_ceiling`), and
the AUC of the prediction against each episode's outcome, beside the rank correlation of
the single measure used before (crossings per minute). The fit is stored as
`calibration.json` in this folder; `dynabarn-worlds stats SET --predict RUNG` applies it.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

CALIBRATION_FILE = Path(__file__).resolve().parent / "calibration.json"
RUNGS = ("straight", "dwa", "teb", "dwa@dwa_dynamic", "teb@teb_dynamic", "predictive", "dagger", "oracle_present")
"""The rungs calibrated: every rung of the ladder below the exact-future oracle."""
FEATURES = (
    "n_obstacles",
    "corridor_blocked",
    "corridor_occupancy",
    "crossings_per_minute",
    "near_density",
    "crossing_speed",
    "static_blocked",
    "slack",
)
BASELINE = "crossings_per_minute"
"""The single measure calibrated on DWA before (Spearman -0.49): the comparison."""
RIDGE = 1.0
HELD_BACK = 5
"""One world in HELD_BACK (by its sha256) is held back from every fit."""


@dataclass
class WorldOutcomes:
    """One world: its features and, per rung, (successes, episodes)."""

    name: str
    sha256: str
    features: dict[str, float]
    outcomes: dict[str, list[int]] = field(default_factory=dict)

    @property
    def held_back(self) -> bool:
        return int(self.sha256[:8], 16) % HELD_BACK == 0


def gather(results_dirs: list[Path], root: Path, slack: dict[tuple[str, str], float]) -> list[WorldOutcomes]:
    """The worlds of the results folders with the rungs' outcomes there; each world's
    features from its file under `root` (skipped when absent or not the bytes that ran) and
    `slack` {(name, sha256): seconds} from its certificate."""
    import hashlib

    from dynabarn.bench.results import read_results
    from dynabarn.mjcf import read_world
    from dynabarn.world_file import world_bytes
    from dynabarn.worlds.difficulty import calibration_features

    worlds: dict[str, WorldOutcomes] = {}
    for folder in results_dirs:
        for row in read_results(Path(folder) / "results.jsonl"):
            if row.get("retry") or row.get("planner") not in RUNGS or not row.get("world_sha256"):
                continue
            sha = row["world_sha256"]
            if sha not in worlds:
                path = root / row.get("world_file", "")
                data = world_bytes(path) if path.is_file() else b""
                if hashlib.sha256(data).hexdigest() != sha:
                    worlds[sha] = None  # type: ignore[assignment]
                    continue
                features = calibration_features(read_world(path, data))
                features["slack"] = slack.get((row["world"], sha), math.nan)
                worlds[sha] = WorldOutcomes(row["world"], sha, features)
            if worlds[sha] is None:
                continue
            counts = worlds[sha].outcomes.setdefault(row["planner"], [0, 0])
            counts[0] += row["outcome"] == "success"
            counts[1] += 1
    return [w for w in worlds.values() if w is not None]


def fit_logistic(X: np.ndarray, successes: np.ndarray, trials: np.ndarray, ridge: float = RIDGE) -> np.ndarray:
    """Coefficients (intercept first) of a binomial logistic regression with an L2 penalty
    on the slopes, by Newton's method (IRLS)."""
    A = np.column_stack([np.ones(len(X)), X])
    beta = np.zeros(A.shape[1])
    penalty = np.full(A.shape[1], ridge)
    penalty[0] = 0.0
    for _ in range(100):
        p = 1.0 / (1.0 + np.exp(-(A @ beta)))
        gradient = A.T @ (successes - trials * p) - penalty * beta
        hessian = (A * (trials * p * (1 - p))[:, None]).T @ A + np.diag(penalty) + 1e-9 * np.eye(len(beta))
        step = np.linalg.solve(hessian, gradient)
        beta += step
        if np.abs(step).max() < 1e-10:
            break
    return beta


def auc(scores: np.ndarray, positive: np.ndarray) -> float:
    """P(a positive scores above a negative), ties counting a half (Mann-Whitney)."""
    from scipy.stats import rankdata

    n_pos, n_neg = int(positive.sum()), int((~positive).sum())
    if not n_pos or not n_neg:
        return math.nan
    ranks = rankdata(scores)
    return float((ranks[positive].sum() - n_pos * (n_pos + 1) / 2) / (n_pos * n_neg))


def _matrix(worlds: list[WorldOutcomes], mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    X = np.array([[w.features.get(f, math.nan) for f in FEATURES] for w in worlds], dtype=np.float64)
    X = np.where(np.isnan(X), mean, X)  # a world without a certificate: the mean slack
    return (X - mean) / std


def calibrate(worlds: list[WorldOutcomes]) -> dict:
    """Per rung: the fit on the worlds not held back and its scores on those held back."""
    out: dict = {"features": list(FEATURES), "ridge": RIDGE, "held_back": f"sha256 % {HELD_BACK} == 0", "rungs": {}}
    for rung in RUNGS:
        ran = [w for w in worlds if rung in w.outcomes]
        train = [w for w in ran if not w.held_back]
        test = [w for w in ran if w.held_back]
        if len(train) < 20 or len(test) < 5:
            continue
        raw = np.array([[w.features.get(f, math.nan) for f in FEATURES] for w in train], dtype=np.float64)
        mean = np.nanmean(raw, axis=0)
        mean = np.where(np.isnan(mean), 0.0, mean)
        std = np.nanstd(raw, axis=0)
        std = np.where((std > 0) & ~np.isnan(std), std, 1.0)
        k, n = (np.array([w.outcomes[rung][i] for w in train], dtype=np.float64) for i in (0, 1))
        beta = fit_logistic(_matrix(train, mean, std), k, n)
        fit = {"intercept": float(beta[0]), "coef": beta[1:].tolist(), "mean": mean.tolist(), "std": std.tolist()}
        out["rungs"][rung] = fit | {"worlds": len(ran), "held_back": len(test), **_scores(fit, test, rung)}
    return out


def _scores(fit: dict, test: list[WorldOutcomes], rung: str) -> dict:
    from scipy.stats import spearmanr

    p = np.array([predict(fit, w.features) for w in test])
    rate = np.array([w.outcomes[rung][0] / w.outcomes[rung][1] for w in test])
    baseline = np.array([w.features[BASELINE] for w in test])
    episodes = np.repeat(p, [w.outcomes[rung][1] for w in test])
    won = np.concatenate([np.arange(w.outcomes[rung][1]) < w.outcomes[rung][0] for w in test])
    # Difficulty is 1 - predicted success: a negative correlation with success ranks well
    # (the convention of the single measure before it).
    return {
        "spearman": _finite(spearmanr(1.0 - p, rate)[0]),
        "spearman_ceiling": _finite(spearman_ceiling(rate)),
        "auc": _finite(auc(episodes, won)),
        "spearman_baseline": _finite(spearmanr(baseline, rate)[0]),
        "success": float(rate.mean()),
    }


def spearman_ceiling(rate: np.ndarray) -> float:
    """The strongest (most negative) Spearman correlation any difficulty measure without ties
    could reach against these per-world success rates: one that orders the worlds exactly as
    their rates do. Short of -1 where the rates tie: a rung that succeeds in 9 worlds of 10
    ties most of them at 1.0, and no measure can rank worlds its outcomes do not (with nine in
    ten at 1.0 and one at 0 the ceiling is about -0.52). The measured correlation is read
    against it."""
    from scipy.stats import spearmanr

    if len(rate) < 2 or np.all(rate == rate[0]):
        return math.nan
    order = np.argsort(rate, kind="stable")
    untied = np.empty(len(rate))
    untied[order] = np.arange(len(rate))
    return -float(spearmanr(untied, rate)[0])


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def predict(fit: dict, features: dict[str, float]) -> float:
    """A rung's predicted chance of success in a world with these features."""
    x = np.array([features.get(f, math.nan) for f in FEATURES], dtype=np.float64)
    mean, std = np.array(fit["mean"]), np.array(fit["std"])
    x = (np.where(np.isnan(x), mean, x) - mean) / std
    return float(1.0 / (1.0 + math.exp(-(fit["intercept"] + float(np.dot(fit["coef"], x))))))


def read_calibration(path: Path = CALIBRATION_FILE) -> dict:
    from dynabarn.errors import DynabarnError

    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise DynabarnError(f"no calibration at {path}: run benchmarks/calibration.py") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise DynabarnError(f"{path}: not valid JSON ({exc})") from None


def slack_by_world(indexes: list[dict]) -> dict[tuple[str, str], float]:
    """{(world name, sha256): the certificate's slack} from world indexes (barn protocol)."""
    from dynabarn.worldset import own_certificates

    out: dict[tuple[str, str], float] = {}
    for index in indexes:
        for e in index.get("worlds", []):
            record = own_certificates(e).get("barn", {})
            if "slack" in record:
                out[(e.get("name"), e["sha256"])] = float(record["slack"])
    return out


def by_rung(worlds: list[WorldOutcomes]) -> dict[str, int]:
    counts: dict[str, int] = defaultdict(int)
    for w in worlds:
        for rung in w.outcomes:
            counts[rung] += 1
    return dict(counts)
