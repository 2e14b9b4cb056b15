"""What the report's charts need: plotly.js from the `plotly` wheel (inlined into the page,
admitted by its hash: no network), plotly's own stylesheet taken out of that bundle (the
page's policy admits no style a script injects: plotly finds it in place and injects none),
a colour per planner that does not repeat, and the data of the two summary charts
(success against measured difficulty, and per difficulty as in the paper's Fig. 5)."""

from __future__ import annotations

import colorsys
import functools
import math
import re

import numpy as np

from dynabarn.bench.stats import wilson_interval
from dynabarn.bench.summary import DIFFICULTIES, FLOOR, PAPER_FIG5, fig5_groups, paper_planner

MEASURED = "corridor_blocked"
"""The measured difficulty the grid sorts by and the chart's axis (`worlds.difficulty`):
the share of time the straight corridor to the goal is blocked."""
DIFFICULTY_BINS = 5
FLOOR_COLOUR = "#757575"
_STRING = r'"(?:[^"\\]|\\.)*"|\'(?:[^\'\\]|\\.)*\''
_RULE = re.compile(r"\s*(" + _STRING + r"|[A-Za-z_$][\w$]*)\s*:\s*(" + _STRING + r")\s*(,|\})")


@functools.cache
def plotly_bundle() -> tuple[str, str]:
    """(plotly.js, its stylesheet). The stylesheet is the rules object plotly.js would
    insert at load (`{"X,X div": ...}`, X the plot's selector, Y the notifier's), read out of
    the bundle: empty where a future bundle is laid out otherwise (the charts still draw)."""
    import plotly.offline

    js = plotly.offline.get_plotlyjs()
    start = js.find('{"X,X div"')
    rules: list[str] = []
    at = start + 1
    while start >= 0:
        match = _RULE.match(js, at)
        if match is None:
            rules = []
            break
        key = match[1][1:-1] if match[1][0] in "\"'" else match[1]
        selector = re.sub(r"^,", " ,", key).replace("X", ".js-plotly-plot .plotly").replace("Y", ".plotly-notifier")
        rules.append(f"{selector}{{{match[2][1:-1]}}}")
        at = match.end()
        if match[3] == "}":
            break
    return js, "\n".join(rules)


def planner_colours(planners: list[str]) -> dict[str, str]:
    """A colour per planner, distinct for any number: hues a golden angle apart, two
    lightnesses alternating; the floor grey."""
    out = {}
    others = [p for p in planners if p != FLOOR]
    for k, planner in enumerate(others):
        hue = (0.6 + k * 0.381966) % 1.0
        r, g, b = colorsys.hls_to_rgb(hue, 0.42 if k % 2 == 0 else 0.55, 0.75)
        out[planner] = f"#{round(255 * r):02x}{round(255 * g):02x}{round(255 * b):02x}"
    if FLOOR in planners:
        out[FLOOR] = FLOOR_COLOUR
    return out


def measured(world: dict | None) -> float | None:
    value = ((world or {}).get("measured") or {}).get(MEASURED)
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else None


def difficulty_chart(rows: list[dict], worlds: dict[str, dict]) -> dict | None:
    """Success against measured difficulty: worlds in quantile bins of it (equal world
    counts), per planner the bins' success with 95% Wilson intervals; None when fewer worlds
    than bins have a measured difficulty."""
    values = {name: measured(w) for name, w in worlds.items()}
    known = sorted(v for v in values.values() if v is not None)
    if len(known) < DIFFICULTY_BINS:
        return None
    edges = np.quantile(known, np.linspace(0, 1, DIFFICULTY_BINS + 1))
    series = {}
    for planner in sorted({r["planner"] for r in rows}):
        hits, totals = np.zeros(DIFFICULTY_BINS), np.zeros(DIFFICULTY_BINS)
        for r in rows:
            m = values.get(r.get("world"))
            if r["planner"] == planner and m is not None:
                b = min(max(int(np.searchsorted(edges, m, side="right")) - 1, 0), DIFFICULTY_BINS - 1)
                hits[b] += r["outcome"] == "success"
                totals[b] += 1
        points = []
        for b in range(DIFFICULTY_BINS):
            if totals[b]:
                lo, hi = wilson_interval(int(hits[b]), int(totals[b]))
                points.append(
                    {
                        "x": round(float(0.5 * (edges[b] + edges[b + 1])), 4),
                        "rate": hits[b] / totals[b],
                        "lo": lo,
                        "hi": hi,
                        "n": int(totals[b]),
                    }
                )
        series[planner] = points
    return {"edges": [round(float(e), 4) for e in edges], "series": series}


def fig5_chart(summary: list[dict]) -> dict:
    """Success per difficulty and planner with its interval, and the paper's Fig. 5 value
    where it applies (`summary.paper`)."""
    groups = fig5_groups(summary)
    series = {}
    for s in summary:
        if s["difficulty"] in groups:
            series.setdefault(s["planner"], {})[s["difficulty"]] = {
                "rate": s["success"],
                "lo": s["success_lo"],
                "hi": s["success_hi"],
                "n": s["episodes"],
                "paper": s["paper"],
            }
    paper_planners = sorted({p for p in series if paper_planner(p) in PAPER_FIG5})
    return {"groups": groups, "series": series, "paper_planners": paper_planners, "all_groups": list(DIFFICULTIES)}
