"""The statistics of a sweep's rows: binomial intervals, means and medians that skip what
has no finite value, and the skill over the blind floor with an interval clustered by world.

The skill's interval (`paired_difference_interval`) is Tango's score interval for a
difference of paired proportions, on an effective sample size that the worlds' clustering
sets (the design effect of `design_effect`). Unlike a Wald or Student-t interval on the
paired differences, it never leaves [-1, 1] and is never of zero width for a finite sample
(all-success against all-failure on 3 worlds of 10 trials is [-0.12, +1.00]: three worlds
cannot exclude zero; never [+1.00, +1.00]).
Its coverage, beside the clustered Student-t interval used before, was measured by
simulation (`benchmarks/skill_coverage.py`, docs/concepts/statistics.md)."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

Z95 = 1.959963984540054
MIN_WORLDS = 20
"""Fewer worlds than this and a difficulty's skill interval is marked in every table: in
simulation (docs/concepts/statistics.md) its coverage of the true skill stays at or above
0.92 (nominal 0.95) from 20 worlds on in every scenario, and falls to about 0.90 below that
for some mixtures of easy and hard worlds."""


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """95% Wilson score interval of a binomial proportion."""
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    # The interval always contains p; rounding could otherwise put p = 1 just above it.
    return max(0.0, min(p, centre - half)), min(1.0, max(p, centre + half))


def mean_finite(values: list[float]) -> float:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    return sum(vals) / len(vals) if vals else float("nan")


def median_finite(values: list) -> float | None:
    vals = sorted(v for v in values if v is not None and math.isfinite(v))
    if not vals:
        return None
    mid = len(vals) // 2
    return vals[mid] if len(vals) % 2 else 0.5 * (vals[mid - 1] + vals[mid])


def _tango_statistic(delta: np.ndarray, b: np.ndarray, c: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Tango's (1998) score statistic for H0: p1 - p2 = delta, with b pairs (1, 0) and c
    pairs (0, 1) among n; the nuisance p21 at its maximum likelihood under H0 (closed form)."""
    w = -b - c + (2 * n - b + c) * delta
    p21 = (np.sqrt(np.maximum(w * w + 8 * n * c * delta * (1 - delta), 0.0)) - w) / (4 * n)
    variance = n * (2 * p21 + delta * (1 - delta))
    numerator = b - c - n * delta
    # No variance (delta at +-1): the data either are that difference exactly or lie beyond it.
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(
            variance > 1e-12, numerator / np.sqrt(np.maximum(variance, 1e-300)), np.sign(numerator) * np.inf
        )


def tango_interval(b, c, n, z: float = Z95) -> tuple[np.ndarray, np.ndarray]:
    """The 95% score interval of a paired difference of proportions (Tango 1998): every delta
    in [-1, 1] whose score statistic lies within +-z. Arrays or numbers (counts may be
    fractional: effective counts); bisection on all of them at once (60 halvings, below 1e-17)."""
    b, c, n = (np.asarray(v, dtype=float) for v in (b, c, n))
    b, c, n = np.broadcast_arrays(b, c, n)
    estimate = (b - c) / n

    def bound(target: float, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        # The statistic falls as delta rises: find where it crosses `target` in [lo, hi].
        lo, hi = lo.copy(), hi.copy()
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            above = _tango_statistic(mid, b, c, n) > target
            lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
        return 0.5 * (lo + hi)

    minus_one, plus_one = np.full_like(estimate, -1.0), np.full_like(estimate, 1.0)
    lower = np.where(_tango_statistic(minus_one, b, c, n) <= z, -1.0, bound(z, minus_one, estimate))
    upper = np.where(_tango_statistic(plus_one, b, c, n) >= -z, 1.0, bound(-z, estimate, plus_one))
    return np.minimum(lower, estimate), np.maximum(upper, estimate)


def design_effect(differences_by_world: list[list[float]]) -> float:
    """How many times the variance of the mean paired difference exceeds what independent
    pairs would give, because trials of one world are alike: the cluster-robust variance over
    the naive one, in [1, mean trials per world]. Where nothing varies (every pair agrees) the
    data cannot tell, and the upper end is taken: each world counts once."""
    n = sum(len(v) for v in differences_by_world)
    m = len(differences_by_world)
    most = n / m
    if m < 2 or n < 2:
        return most if m else 1.0
    mean = sum(sum(v) for v in differences_by_world) / n
    naive = sum((d - mean) ** 2 for v in differences_by_world for d in v) / (n - 1) / n
    if naive <= 0:
        return most
    clustered = sum((sum(v) - len(v) * mean) ** 2 for v in differences_by_world) * m / (m - 1) / (n * n)
    return min(max(clustered / naive, 1.0), most)


def paired_difference_interval(differences_by_world: list[list[float]]) -> tuple[float, float, float]:
    """(estimate, lower, upper) of the mean of paired differences in {-1, 0, +1}, grouped by
    world: Tango's score interval on the counts divided by the design effect."""
    flat = [d for v in differences_by_world for d in v]
    n = len(flat)
    b, c = sum(d > 0 for d in flat), sum(d < 0 for d in flat)
    deff = design_effect(differences_by_world)
    lo, hi = tango_interval(b / deff, c / deff, n / deff)
    return (b - c) / n, float(lo), float(hi)


def skill_over_floor(rows: list[dict], floor_rows: list[dict]) -> dict:
    """Success minus the floor's on the shared (world, seed) episodes, with its 95% interval
    (`paired_difference_interval`) and the number of worlds it rests on (`skill_worlds`;
    under `MIN_WORLDS` the tables mark it). Empty dict when no episode is shared."""
    floor = {(r["world"], r["seed"]): r["outcome"] == "success" for r in floor_rows if "world" in r}
    by_world: dict[str, list[float]] = defaultdict(list)
    floor_hits = 0
    for r in rows:
        key = (r.get("world"), r["seed"])
        if key in floor:
            by_world[key[0]].append(float(r["outcome"] == "success") - float(floor[key]))
            floor_hits += floor[key]
    n = sum(len(v) for v in by_world.values())
    if n == 0:
        return {}
    skill, lo, hi = paired_difference_interval(list(by_world.values()))
    return {"floor": floor_hits / n, "skill": skill, "skill_lo": lo, "skill_hi": hi, "skill_worlds": len(by_world)}


def skill_text(s: dict) -> str:
    """A summary row's skill as the tables print it: `+0.25 [+0.10, +0.40]`, a dagger where
    it rests on fewer than `MIN_WORLDS` worlds, `-` where there is none."""
    if s.get("skill") is None:
        return "-"
    return difference_text(s["skill"], s["skill_lo"], s["skill_hi"], s.get("skill_worlds") or 0)


def difference_text(estimate: float, lo: float, hi: float, worlds: int) -> str:
    """A paired difference with its interval, `+0.25 [+0.10, +0.40]`, and a dagger where it
    rests on fewer than `MIN_WORLDS` worlds (the skill over the floor, `--compare`'s A - B)."""
    few = "\u2020" if worlds < MIN_WORLDS else ""
    return f"{estimate:+.2f} [{lo:+.2f}, {hi:+.2f}]{few}"


FEW_WORLDS_NOTE = (
    f"\u2020 fewer than {MIN_WORLDS} worlds: in simulation the interval's coverage falls to about 90 % there "
    "(docs/concepts/statistics.md); read it as a rough guide."
)
