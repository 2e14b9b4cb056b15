"""The statistics of a sweep's rows: binomial intervals, means and medians that skip what
has no finite value, and the skill over the blind floor with an interval clustered by world."""

from __future__ import annotations

import math
from collections import defaultdict


def wilson_interval(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
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


def skill_over_floor(rows: list[dict], floor_rows: list[dict]) -> dict:
    """Success minus the floor's on the shared (world, seed) episodes, with a 95% interval
    clustered by world. Empty dict when no episode is shared."""
    from scipy.stats import t as student_t

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
    diff = sum(sum(v) for v in by_world.values()) / n
    m = len(by_world)
    if m < 2:
        return {"floor": floor_hits / n, "skill": diff, "skill_lo": float("nan"), "skill_hi": float("nan")}
    # Cluster-robust standard error of a mean (worlds as clusters, small-sample factor m/(m-1)).
    se = math.sqrt(sum((sum(v) - len(v) * diff) ** 2 for v in by_world.values()) * m / (m - 1)) / n
    half = float(student_t.ppf(0.975, m - 1)) * se
    return {"floor": floor_hits / n, "skill": diff, "skill_lo": diff - half, "skill_hi": diff + half}
