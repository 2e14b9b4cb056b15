"""The summary per planner and difficulty: success rate with a 95% Wilson interval,
collision and timeout rates, mean time of successes, BARN score, SPL and minimum
clearance, and the skill over the blind floor; printed, and written as `summary.csv`,
`summary.md` and a Fig. 5-style `fig5.png` with the paper's published values and the
floor beside ours.

The floor is `straight` (drive at the goal at 2 m/s, avoid nothing) on the same worlds
and seeds: how much of a difficulty blind speed alone solves. A planner's skill is its
success minus the floor's on the same (world, seed) pairs; its 95% interval is a score
interval for paired proportions on the worlds' effective sample size (`stats`,
docs/concepts/statistics.md), marked where it rests on fewer than `stats.MIN_WORLDS` worlds."""

from __future__ import annotations

import csv
import io
import math
from collections import defaultdict
from functools import partial
from pathlib import Path

from dynabarn.bench.stats import (
    FEW_WORLDS_NOTE,
    MIN_WORLDS,
    mean_finite,
    median_finite,
    skill_over_floor,
    skill_text,
    wilson_interval,
)
from dynabarn.files import save_atomically, write_atomically
from dynabarn.metric_registry import added_metrics
from dynabarn.metrics import METRICS
from dynabarn.worlds.profiles import Difficulty

PAPER_FIG5 = {
    "dwa": {"easy": 0.78, "medium": 0.43, "hard": 0.17},
    "teb": {"easy": 0.40, "medium": 0.16, "hard": 0.00},
    "bc": {"easy": 0.30, "medium": 0.08, "hard": 0.05},
    "td3": {"easy": 0.74, "medium": 0.60, "hard": 0.28},
}
"""The paper's Fig. 5 success rates (read off the bar chart, +-0.02)."""


DIFFICULTIES = tuple(d.value for d in Difficulty)
FLOOR = "straight"
"""The blind floor every planner is measured against."""


def summarised_metrics(rows: list[dict], successes: list[dict]) -> dict:
    """Each metric a summary shows (`metrics.METRICS`, `summary`): the mean over the rows
    (`NAME`; a row without it counts as its `when_missing`) or over the successful ones
    (`NAME_success`), in the table's order."""
    out = {}
    for m in METRICS:
        if m.summary == "mean":
            out[m.name] = mean_finite([r.get(m.name, m.when_missing) for r in rows])
        elif m.summary == "successes":
            out[f"{m.name}_success"] = mean_finite([r.get(m.name) for r in successes])
    # Metrics added beyond the table (`metric_registry`): every group has the column (a
    # table's rows share their keys), from the rows that have a value.
    for m in added_metrics():
        value = partial(_added, m)
        if m.summary == "mean":
            out[m.name] = mean_finite([value(r) for r in rows])
        elif m.summary == "successes":
            out[f"{m.name}_success"] = mean_finite([value(r) for r in successes])
    return out


def _added(metric, row: dict):
    """A row's value of a metric added beyond the table (its `when_missing` where it has none)."""
    added = row.get("added_metrics")
    value = added.get(metric.name) if isinstance(added, dict) else None
    if isinstance(value, bool) or not isinstance(value, int | float):  # a row is untrusted input
        value = None
    return metric.when_missing if value is None else value


PAPER_PROTOCOLS = ("barn", "paper2022")
PAPER_PRESETS = ("dwa_dynabarn_authors", "teb_ros_defaults")
"""Presets that are the paper's planners as its authors configured them: compared with its
bars. Other presets (e.g. `dwa@dwa_dynamic`) are planners the paper does not have."""


def paper_planner(planner: str) -> str | None:
    """The paper's planner a result row's planner stands for (`dwa`, `dwa@dwa_dynabarn_authors`
    -> dwa), or None when it stands for none the paper ran."""
    base, _, preset = planner.partition("@")
    return base if base in PAPER_FIG5 and (not preset or preset in PAPER_PRESETS) else None


TRACKING_SUMMARY = {
    "track_recall": "recall",
    "track_precision": "precision",
    "track_pos_err": "position_error_median",
    "track_pos_err_p95": "position_error_p95",
    "track_vel_err": "velocity_error_median",
    "track_vel_err_p95": "velocity_error_p95",
    "track_id_switches": "id_switches",
}
"""Summary column -> the episode's `tracking` field it summarises: the median over the
episodes of the episode's value (identity switches: the mean per episode)."""


def tracking_summary(rows: list[dict]) -> dict:
    """The tracking columns for a group of rows: all None when no row has a tracker."""
    tracked = [r["tracking"] for r in rows if isinstance(r.get("tracking"), dict)]
    out: dict = {column: None for column in TRACKING_SUMMARY}
    if tracked:
        for column, key in TRACKING_SUMMARY.items():
            values = [t.get(key) for t in tracked]
            out[column] = mean_finite(values) if key == "id_switches" else median_finite(values)
    return out


def privileged(planner: str) -> bool:
    """Whether a result row's planner (`NAME` or `NAME@PRESET`) reads the true obstacle
    states: marked in every table (a rung of the ladder, not a robot's planner)."""
    from dynabarn.errors import DynabarnError
    from dynabarn.planners.registry import privileged as declared_privileged

    try:
        return declared_privileged(planner.split("@")[0])
    except DynabarnError:  # a planner no longer installed: its rows still summarise
        return False


def certified_success(rows: list[dict], certified: dict) -> dict:
    """Success over the episodes whose world and trial are certified solvable
    (`results.certified_episodes`), with its interval; None where no episode has a certificate."""
    known = [r for r in rows if r.get("seed") in certified.get((r.get("world"), r.get("protocol")), ((), ()))[1]]
    if not known:
        return {
            "certified_episodes": None,
            "certificate_known": 0,
            "success_certified": None,
            "certified_lo": None,
            "certified_hi": None,
        }
    sure = [r for r in known if r["seed"] in certified[(r["world"], r["protocol"])][0]]
    k = sum(r["outcome"] == "success" for r in sure)
    lo, hi = wilson_interval(k, len(sure)) if sure else (math.nan, math.nan)
    return {
        "certified_episodes": len(sure),
        "certificate_known": len(known),
        "success_certified": k / len(sure) if sure else None,
        "certified_lo": lo,
        "certified_hi": hi,
    }


def summarise(rows: list[dict], paper_worlds: set[str] = frozenset(), certified: dict | None = None) -> list[dict]:
    """One summary row per (planner, difficulty), plus 'all' per planner. The paper's Fig. 5
    value is given only where every episode ran under one of the paper's protocols in a
    world of `paper_worlds` (whose provenance is the paper's: `results.paper_worlds`). With
    `certified` (`results.certified_episodes`), success over the certified episodes too."""
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for r in rows:
        groups[(r["planner"], r["difficulty"])].append(r)
        groups[(r["planner"], "all")].append(r)
    out = []
    order = {d: i for i, d in enumerate((*DIFFICULTIES, "all"))}
    none = {"floor": None, "skill": None, "skill_lo": None, "skill_hi": None, "skill_worlds": None}
    for (planner, difficulty), rs in sorted(groups.items(), key=lambda kv: (kv[0][0], order.get(kv[0][1], 9))):
        n = len(rs)
        k = sum(r["outcome"] == "success" for r in rs)
        lo, hi = wilson_interval(k, n)
        succ = [r for r in rs if r["outcome"] == "success"]
        out.append(
            {
                "planner": planner,
                "difficulty": difficulty,
                "episodes": n,
                "success": k / n,
                "success_lo": lo,
                "success_hi": hi,
                "collision": sum(r["outcome"] == "collision" for r in rs) / n,
                "timeout": sum(r["outcome"] == "timeout" for r in rs) / n,
                "error": sum(r["outcome"] == "error" for r in rs) / n,
                **summarised_metrics(rs, succ),
                "privileged": privileged(planner),
                # The paper's Fig. 5 only compares with runs in the paper's worlds under its protocols.
                "paper": PAPER_FIG5.get(paper_planner(planner) or "", {}).get(difficulty)
                if all(r.get("protocol") in PAPER_PROTOCOLS and r.get("world") in paper_worlds for r in rs)
                else None,
                **(
                    none | skill_over_floor(rs, groups[(FLOOR, difficulty)])
                    if planner != FLOOR and (FLOOR, difficulty) in groups
                    else none
                ),
                **tracking_summary(rs),
                **(certified_success(rs, certified) if certified else {}),
            }
        )
    return out


def few_worlds(summary: list[dict]) -> bool:
    """Whether any skill in the table rests on fewer than `MIN_WORLDS` worlds (its footnote)."""
    return any(s.get("skill") is not None and (s.get("skill_worlds") or 0) < MIN_WORLDS for s in summary)


def _finite(value: float | None, fmt: str) -> str:
    """A mean as the tables print it: `-` where there is nothing to average (never `nan`)."""
    return "-" if value is None or not math.isfinite(value) else format(value, fmt)


def format_table(summary: list[dict]) -> str:
    wp = max([10, *(len(_label(s)) + 2 for s in summary)])
    head = (
        f"{'planner':<{wp}}{'difficulty':<11}{'n':>5}{'success [95% CI]':>22}{'coll':>7}{'timeout':>8}"
        f"{'t_succ':>8}{'score':>7}{'SPL':>6}{'clear':>7}{'paper':>7}  {'skill over floor [95% CI]'}"
    )
    lines = [head, "-" * len(head)]
    for s in summary:
        ci = f"{s['success']:.2f} [{s['success_lo']:.2f}, {s['success_hi']:.2f}]"
        paper = f"{s['paper']:.2f}" if s["paper"] is not None else "-"
        lines.append(
            f"{_label(s):<{wp}}{s['difficulty']:<11}{s['episodes']:>5}{ci:>22}{s['collision']:>7.2f}"
            f"{s['timeout']:>8.2f}{_finite(s['time_success'], '.1f'):>8}{s['score']:>7.3f}{s['spl']:>6.2f}"
            f"{_finite(s['min_clearance'], '.2f'):>7}{paper:>7}  {skill_text(s)}"
        )
    if few_worlds(summary):
        lines.append(FEW_WORLDS_NOTE)
    tracked = [s for s in summary if s.get("track_recall") is not None]
    if tracked:
        lines += ["", tracking_table(tracked, markdown=False)]
    if any(s.get("certified_episodes") is not None for s in summary):
        lines += ["", certified_table(summary)]
    return "\n".join(lines)


def certified_table(summary: list[dict]) -> str:
    """Success over all episodes beside success over the certified ones (`dynabarn-worlds
    certify`): a failure where no witness exists is not the planner's."""
    wp = max([10, *(len(_label(s)) + 2 for s in summary)])
    head = f"{'planner':<{wp}}{'difficulty':<11}{'n':>5}{'success':>9}{'certified n':>13}"
    head += f"{'success [95% CI] on certified':>32}"
    lines = [head, "-" * len(head)]
    for s in summary:
        if s.get("certified_episodes") is None:
            continue
        on = "-"
        if s["success_certified"] is not None:
            on = f"{s['success_certified']:.2f} [{s['certified_lo']:.2f}, {s['certified_hi']:.2f}]"
        n_c = f"{s['certified_episodes']}/{s['certificate_known']}"
        lines.append(f"{_label(s):<{wp}}{s['difficulty']:<11}{s['episodes']:>5}{s['success']:>9.2f}{n_c:>13}{on:>32}")
    return "\n".join(lines)


def _label(s: dict) -> str:
    return f"{s['planner']} (privileged)" if s.get("privileged") else s["planner"]


def _num(value, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def _mm(metres, fmt: str) -> str:
    return "-" if metres is None else format(1000 * metres, fmt)


def tracking_table(summary: list[dict], *, markdown: bool = True) -> str:
    """Tracking quality of the planners with a tracker (medians over episodes)."""
    head = [
        "planner",
        "difficulty",
        "recall",
        "precision",
        "position error median / p95 [mm]",
        "velocity error median / p95 [m/s]",
        "identity switches per episode",
    ]
    rows = [
        [
            s["planner"],
            s["difficulty"],
            _num(s["track_recall"], ".3f"),
            _num(s["track_precision"], ".3f"),
            f"{_mm(s['track_pos_err'], '.1f')} / {_mm(s['track_pos_err_p95'], '.0f')}",
            f"{_num(s['track_vel_err'], '.3f')} / {_num(s['track_vel_err_p95'], '.3f')}",
            _num(s["track_id_switches"], ".1f"),
        ]
        for s in summary
        if s.get("track_recall") is not None
    ]
    if markdown:
        return "\n".join(
            ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + ["| " + " | ".join(r) + " |" for r in rows]
        )
    widths = [max(len(h), *(len(r[i]) for r in rows)) + 2 for i, h in enumerate(head)]
    return "\n".join("".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in [head, *rows])


def write_summary(summary: list[dict], out_dir: Path, *, title: str = "") -> dict[str, Path]:
    paths = {"csv": out_dir / "summary.csv", "md": out_dir / "summary.md", "png": out_dir / "fig5.png"}
    table = io.StringIO(newline="")
    w = csv.DictWriter(table, fieldnames=list(summary[0].keys()))
    w.writeheader()
    w.writerows(summary)
    write_atomically(paths["csv"], table.getvalue())
    md = [
        "| planner | difficulty | episodes | success [95% CI] | collision | timeout | mean time of successes [s] "
        "| score | SPL | min clearance [m] | paper | floor | skill over floor [95% CI] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in summary:
        paper = f"{s['paper']:.2f}" if s["paper"] is not None else "-"
        md.append(
            f"| {_label(s)} | {s['difficulty']} | {s['episodes']} | {s['success']:.2f} "
            f"[{s['success_lo']:.2f}, {s['success_hi']:.2f}] | {s['collision']:.2f} | {s['timeout']:.2f} | "
            f"{_finite(s['time_success'], '.1f')} | {s['score']:.3f} | {s['spl']:.2f} | "
            f"{_finite(s['min_clearance'], '.2f')} | {paper} | "
            f"{'-' if s.get('floor') is None else format(s['floor'], '.2f')} | {skill_text(s)} |"
        )
    if few_worlds(summary):
        md += ["", FEW_WORLDS_NOTE]
    if any(s.get("track_recall") is not None for s in summary):
        md += [
            "",
            "Tracking quality (planners with a laser tracker; medians over episodes):",
            "",
            tracking_table(summary),
        ]
    if any(s.get("certified_episodes") is not None for s in summary):
        md += [
            "",
            "Success over the episodes whose world and trial are certified solvable (`dynabarn-worlds certify`):",
            "",
            "```",
            certified_table(summary),
            "```",
        ]
    write_atomically(paths["md"], (f"# {title}\n\n" if title else "") + "\n".join(md) + "\n")
    plot_fig5(summary, paths["png"], title=title)
    return paths


def fig5_groups(summary: list[dict]) -> list[str]:
    """The difficulties Fig. 5 draws: those with episodes (a sweep of hard worlds only is one
    group, not two empty ones beside it)."""
    present = {s["difficulty"] for s in summary}
    return [d for d in DIFFICULTIES if d in present]


def plot_fig5(summary: list[dict], path: Path, *, title: str = "", order: tuple[str, ...] = ()) -> Path:
    """Bars of success per difficulty with 95% intervals, the paper's values as hatched bars;
    planners in `order` first, in that order (default: the floor, then by name)."""
    # A Figure of its own, not pyplot: no global backend switch, no figure registry.
    import numpy as np
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    groups = fig5_groups(summary)
    rank = {p: i for i, p in enumerate(order or (FLOOR,))}
    planners = sorted({s["planner"] for s in summary}, key=lambda p: (rank.get(p, len(rank)), p))
    fig = Figure(figsize=(2.2 + 2.4 * len(planners), 4.0), dpi=120)
    ax = fig.subplots()
    width = 0.8 / (2 * len(planners))
    colors = colormaps.get_cmap("tab10")
    x = np.arange(len(groups))
    for k, planner in enumerate(planners):
        rows = {s["difficulty"]: s for s in summary if s["planner"] == planner}
        ours = [rows[d]["success"] if d in rows else np.nan for d in groups]
        err = np.array(
            [
                [rows[d]["success"] - rows[d]["success_lo"], rows[d]["success_hi"] - rows[d]["success"]]
                if d in rows
                else [0, 0]
                for d in groups
            ]
        ).T
        pos = x - 0.4 + width * (2 * k + 0.5)
        color = "0.6" if planner == FLOOR else colors(k)
        label = f"{planner} (blind floor)" if planner == FLOOR else f"{planner} (ours)"
        ax.bar(pos, ours, width, yerr=err, capsize=3, color=color, label=label)
        if planner == FLOOR:  # the floor as a line across each difficulty's group
            for xi, value in zip(x, ours, strict=True):
                ax.hlines(value, xi - 0.42, xi + 0.42, colors="0.3", linestyles="--", linewidth=1)
        paper = [rows[d]["paper"] if d in rows and rows[d]["paper"] is not None else np.nan for d in groups]
        if not all(np.isnan(paper)):
            ax.bar(
                pos + width, paper, width, color="white", edgecolor=colors(k), hatch="//", label=f"{planner} (paper)"
            )
    ax.set_xticks(x, groups)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("success rate")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, ncol=min(4, max(1, len(planners))), loc="upper center", bbox_to_anchor=(0.5, -0.08))
    ax.set_title(title or "success rate per difficulty (95% Wilson intervals)", fontsize=10)
    fig.tight_layout()
    save_atomically(path, lambda f: fig.savefig(f, format="png", bbox_inches="tight"))
    return path
