"""How often the skill interval covers the true skill (issue 56): simulated sweeps with known
rates, the interval used now (`stats.paired_difference_interval`: Tango's score interval on
a design-effect sample size) beside the clustered Student-t interval used before and a
cluster (world) bootstrap.

A simulated sweep: m worlds, t trials each. Each world draws its own success probability
for the planner and for the floor from Beta distributions with the scenario's means, tied
by one uniform per world (a world hard for one is hard for the other), so trials of a world
are alike, as in a real sweep. The true skill is the difference of the means. Writes
`results/statistics/skill_coverage.json` and the table between the markers of
docs/concepts/statistics.md:

    python benchmarks/skill_coverage.py            # about half a minute on 2 cores
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
from scipy.stats import beta as beta_distribution
from scipy.stats import t as student_t

from dynabarn.bench.stats import MIN_WORLDS, design_effect, tango_interval
from dynabarn.files import write_atomically

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "statistics" / "skill_coverage.json"
PAGE = ROOT / "docs" / "concepts" / "statistics.md"
SEED = 56
WORLDS = (3, 6, 10, 20, 60)
TRIALS = (1, 10)
RATES = ((0.9, 0.1), (0.5, 0.5), (0.7, 0.4), (0.97, 0.85), (0.25, 0.05))
"""(planner, floor) mean success: far apart, equal, between, both near the top, both low."""
CONCENTRATION = 2.0
"""Beta(mean * k, (1 - mean) * k): k = 2 spreads worlds from easy to hard, as the tiers do."""
BOOTSTRAP = 300


def simulate(rng, m: int, t: int, rates: tuple[float, float], reps: int) -> np.ndarray:
    """Paired differences, shape (reps, m, t), in {-1, 0, +1}."""
    u = rng.uniform(size=(reps, m, 1))
    probabilities = [
        beta_distribution.ppf(u, mean * CONCENTRATION, (1 - mean) * CONCENTRATION) if 0 < mean < 1 else u * 0 + mean
        for mean in rates
    ]
    planner = rng.uniform(size=(reps, m, t)) < probabilities[0]
    floor = rng.uniform(size=(reps, m, t)) < probabilities[1]
    return planner.astype(float) - floor.astype(float)


def clustered_t(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The interval used before issue 56: cluster-robust standard error, Student t on m - 1."""
    _reps, m, t = d.shape
    n = m * t
    mean = d.sum(axis=(1, 2)) / n
    se = np.sqrt(((d.sum(axis=2) - t * mean[:, None]) ** 2).sum(axis=1) * m / (m - 1)) / n
    half = student_t.ppf(0.975, m - 1) * se
    return mean - half, mean + half


def score_design_effect(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`stats.paired_difference_interval` over the simulated sweeps: the library's own
    `design_effect` per sweep (what is measured is what the tables use), Tango's interval
    on all of them at once."""
    _reps, m, t = d.shape
    deff = np.array([design_effect(sweep.tolist()) for sweep in d])
    b, c = (d > 0).sum(axis=(1, 2)), (d < 0).sum(axis=(1, 2))
    return tango_interval(b / deff, c / deff, m * t / deff)


def cluster_bootstrap(rng, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Percentile interval of the mean over worlds drawn with replacement."""
    reps, m, _t = d.shape
    per_world = d.mean(axis=2)
    picks = rng.integers(0, m, size=(reps, BOOTSTRAP, m))
    means = np.take_along_axis(per_world[:, None, :].repeat(BOOTSTRAP, axis=1), picks, axis=2).mean(axis=2)
    return np.quantile(means, 0.025, axis=1), np.quantile(means, 0.975, axis=1)


METHODS = {"score, design effect (now)": score_design_effect, "clustered Student t (before)": clustered_t}


def run(reps: int) -> list[dict]:
    rng = np.random.default_rng(SEED)
    out = []
    for m in WORLDS:
        for t in TRIALS:
            for rates in RATES:
                d = simulate(rng, m, t, rates, reps)
                truth = rates[0] - rates[1]
                intervals = {name: method(d) for name, method in METHODS.items()}
                intervals["world bootstrap"] = cluster_bootstrap(rng, d)
                row = {"worlds": m, "trials": t, "planner": rates[0], "floor": rates[1], "truth": truth}
                for name, (lo, hi) in intervals.items():
                    row[name] = {
                        "coverage": float(np.mean((lo <= truth + 1e-12) & (truth - 1e-12 <= hi))),
                        "outside": float(np.mean((lo < -1 - 1e-9) | (hi > 1 + 1e-9))),
                        "zero_width": float(np.mean(hi - lo < 1e-9)),
                        "mean_width": float(np.mean(np.minimum(hi, 1) - np.maximum(lo, -1))),
                    }
                out.append(row)
    return out


def table(rows: list[dict]) -> str:
    names = [*METHODS, "world bootstrap"]
    head = "| worlds | trials | planner, floor | " + " | ".join(f"{n}: coverage / zero-width / outside" for n in names)
    lines = [head + " |", "|" + "---|" * (3 + len(names))]
    for r in rows:
        cells = [f"{r[n]['coverage']:.3f} / {r[n]['zero_width']:.2f} / {r[n]['outside']:.2f}" for n in names]
        lines.append(
            f"| {r['worlds']} | {r['trials']} | {r['planner']:.2f}, {r['floor']:.2f} | " + " | ".join(cells) + " |"
        )
    worst = {m: min(r[names[0]]["coverage"] for r in rows if r["worlds"] == m) for m in WORLDS}
    lines += [
        "",
        "Lowest coverage of the interval used now, per number of worlds: "
        + ", ".join(f"{m} worlds {c:.3f}" for m, c in worst.items())
        + f". Tables mark a skill resting on fewer than {MIN_WORLDS} worlds.",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--reps", type=int, default=2000, help="simulated sweeps per scenario (default: 2000)")
    args = parser.parse_args()
    rows = run(args.reps)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(OUT, json.dumps({"seed": SEED, "reps": args.reps, "rows": rows}, indent=1) + "\n")
    text = PAGE.read_text()
    new = re.sub(
        r"(<!-- coverage -->\n).*?(\n<!-- /coverage -->)", lambda m: m[1] + table(rows) + m[2], text, flags=re.S
    )
    write_atomically(PAGE, new)
    print(table(rows))


if __name__ == "__main__":
    main()
