"""The result tables and figures of the README and the documentation, generated from the
committed results folder.

`python benchmarks/readme_results.py` (`make readme`) rewrites every block between
`<!-- results:NAME -->` and `<!-- /results:NAME -->` of the pages in `PAGES` (README.md,
docs/results.md, docs/tutorials/training.md and ros.md) from `results/` and redraws the figures in
`docs/assets/`; `--check` only compares and exits 1 when a page is not what the results
say (a test runs it). The results come from `dynabarn-bench` sweeps
(docs/results.md gives the commands); nothing here runs an episode.

results/
  paper60_barn/    the paper's 60 generated worlds (ids 0-19, 100-109, 150-159, 200-219)
  original60_barn/ the release's 60 worlds, imported with `dynabarn-worlds import`
  unseen_barn/     the 240 generated worlds the learned policies never trained on
  move_base_*/     real move_base beside our DWA with its configuration (ros_tables.py)
  move_base_dwa_ablation/ the outcomes of each difference between the two (dwa_ablation.py)
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections import defaultdict
from pathlib import Path

from dynabarn.bench import DIFFICULTIES, PAPER_FIG5, paper_worlds, read_results, summarise
from dynabarn.bench.results import RESULTS, WORLDS
from dynabarn.bench.stats import skill_text, wilson_interval
from dynabarn.bench.summary import FLOOR, plot_fig5

sys.path.insert(0, str(Path(__file__).resolve().parent))
from certified_tables import calibration_table, certification_table, certified_ladder, certified_sets
from leaderboard import leaderboard_table, tier_ladder_table
from learning_tables import dagger_curves, dagger_training, generalisation_table, student_ablation, student_table
from perception_aims import aims_tables
from ros_speed import table as ros_speed_table
from ros_tables import MOVE_BASE_SETS, NAV2_FOLDERS, STACK_GUESTS, ablation_table, move_base_table, nav2_table
from tracker_tables import (
    LADDERS,
    TEB_PADDING,
    TRACKER_FOLDERS,
    anatomy_table,
    gap_table,
    padding_table,
    tracker_table,
    validation_table,
)
from warp_agreement import read_records as warp_agreement_records
from warp_agreement import table as warp_agreement_table
from warp_speed import read_records as warp_speed_records
from warp_speed import table as warp_speed_table
from warp_student import table as warp_student_table

ROOT = Path(__file__).resolve().parents[1]
RESULTS_DIR = ROOT / "results"
README = ROOT / "README.md"
DOCS = ROOT / "docs"
FIGURES = DOCS / "assets"
TD3_TRAINING = RESULTS_DIR / "td3_training" / "training.json"

SETS = {
    "paper60_barn": "paper60",
    "original60_barn": "original 60",
    "unseen_barn": "unseen 240",
}
OTHER_SETS = {
    "mixed_hard_barn": "mixed shapes, a static BARN field (`--static barn-grid --shapes mixed`), hard worlds 200-299",
    "mixed_easy_medium_barn": "mixed shapes, a static BARN field, easy and medium worlds 0-199",
    "shaped_hard_barn": "mixed shapes (`--shapes mixed`), hard worlds 200-299",
    "yield_hard_barn": "obstacles that yield (`--behavior yield`), hard worlds 200-299",
    "avoid_hard_barn": "obstacles that steer around the robot (`--behavior avoid`), hard worlds 200-299",
}
"""Beyond the paper's worlds: one trial per world (folders written by the commands in docs/results.md)."""
TIER_SETS = {
    "tier_dense_barn": "`tier-dense`: 20-29 / 30-40 obstacles",
    "tier_fast_barn": "`tier-fast`: up to 2.5 m/s, orders up to 6",
    "tier_mixed_barn": "`tier-mixed`: a static BARN field, mixed shapes",
    "tier_combined_barn": "`tier-combined`: all of them",
}
"""The tiers beyond the paper's hard, 10 trials per world, every world certified solvable."""
LEADERBOARD_SETS = {
    **SETS,
    **TIER_SETS,
    **OTHER_SETS,
    **{
        folder: f"{LADDERS[world_set][0]}, hard worlds: the `{preset}` preset"
        for folder, (preset, world_set) in TRACKER_FOLDERS.items()
    },
}
"""The leaderboard's world sets, in its order."""
PLANNERS = {
    FLOOR: "Blind floor (`straight`)",
    "dwa": "DWA, our defaults (ROS's DWA biases, 2 m/s)",
    "dwa@dwa_dynabarn_authors": "DWA, the authors' move_base configuration (`dwa@dwa_dynabarn_authors`)",
    "teb": "TEB, our defaults (2 m/s)",
    "teb@teb_ros_defaults": "TEB, teb_local_planner's defaults as the authors ran it (`teb@teb_ros_defaults`)",
    "bc": "BC (shipped `bc.pt`)",
    "td3": "TD3 (shipped `td3.pt`)",
    "dagger": "DAgger student taught by `predictive`, procedural training worlds only (shipped `dagger_predictive.pt`)",
    "dwa@dwa_dynamic": "DWA with the laser tracker's predictions (`dwa@dwa_dynamic`)",
    "teb@teb_dynamic": "TEB with the laser tracker's predictions (`teb@teb_dynamic`)",
    "teb@teb_dynamic_uncertain": "TEB with the laser tracker's predictions grown by their uncertainty "
    "(`teb@teb_dynamic_uncertain`)",
    "predictive": "The laser tracker feeding the oracle's search (`predictive`)",
    "predictive@shaped_tracker": "`predictive` with the tracker for boxes, capsules and cylinders "
    "(`predictive@shaped_tracker`)",
    "predictive@registered_tracker": "`predictive` with velocities from registered returns "
    "(`predictive@registered_tracker`)",
    "oracle_present": "*Privileged*: the true present state, constant velocity (`oracle_present`)",
    "oracle": "*Privileged*: the exact future (`oracle`)",
}
LADDER = (
    (FLOOR, "blind", "the blind floor: drive at the goal, avoid nothing"),
    ("dwa", "laser", "reactive: DWA, each scan a static snapshot"),
    ("teb", "laser", "reactive: TEB, each scan a static snapshot"),
    ("dwa@dwa_dynamic", "laser", "DWA + tracker predictions"),
    ("teb@teb_dynamic", "laser", "TEB + tracker predictions"),
    ("predictive", "laser", "tracker predictions + the oracle's search"),
    ("oracle_present", "privileged", "true present state, constant velocity, the oracle's search"),
    ("oracle", "privileged", "the exact future, the oracle's search"),
)
"""The ladder from blind to all-knowing: (planner, what it sees, what it is)."""
PAPER_NAMES = {"dwa": "DWA", "teb": "TEB", "bc": "BC", "td3": "TD3"}


def _ci(s: dict) -> str:
    return f"{s['success']:.2f} [{s['success_lo']:.2f}, {s['success_hi']:.2f}]"


def _skill(s: dict) -> str:
    if s.get("skill") is None:
        return "-"
    return skill_text(s)


def _record(name: str) -> dict | None:
    """A committed benchmark record under results/ (None where it is absent)."""
    path = RESULTS_DIR / name
    return json.loads(path.read_text()) if path.is_file() else None


def load(folder: str) -> tuple[list[dict], list[dict]]:
    """(rows, summary) of one results folder; empty when it is absent."""
    rows = [r for r in read_results(RESULTS_DIR / folder / RESULTS) if not r.get("retry")]
    return rows, summarise(rows, paper_worlds(RESULTS_DIR / folder)) if rows else []


def load_all() -> tuple[dict, dict]:
    """(folders, summaries): every results folder the pages use as (rows, summary), and the
    summaries of the paper's two world sets and the unseen worlds."""
    everything = (*SETS, *OTHER_SETS, *TIER_SETS, *MOVE_BASE_SETS, *NAV2_FOLDERS, *TRACKER_FOLDERS)
    folders = {folder: load(folder) for folder in everything}
    return folders, {folder: s for folder, (_, s) in folders.items() if folder in SETS}


def _by(summary: list[dict]) -> dict[tuple[str, str], dict]:
    return {(s["planner"], s["difficulty"]): s for s in summary}


def fig5_table(summaries: dict[str, list[dict]]) -> str:
    """Success per difficulty: the paper's bar, then ours on each world set, planner by planner."""
    lines = ["| planner | worlds | episodes | easy | medium | hard |", "|---|---|---|---|---|---|"]
    for planner, title in PLANNERS.items():
        base = planner.split("@")[0]
        if base in PAPER_FIG5 and planner == base:
            p = PAPER_FIG5[base]
            lines.append(
                f"| {PAPER_NAMES[base]}, **paper** | the paper's 60 | 200 per difficulty | "
                + " | ".join(f"{p[d]:.2f}" for d in DIFFICULTIES)
                + " |"
            )
        for folder in ("paper60_barn", "original60_barn"):
            by = _by(summaries.get(folder, []))
            if (planner, "all") not in by:
                continue
            cells = [(_ci(by[(planner, d)]) if (planner, d) in by else "-") for d in DIFFICULTIES]
            lines.append(
                f"| {title} | {SETS[folder]} | {by[(planner, 'all')]['episodes']} | " + " | ".join(cells) + " |"
            )
    return "\n".join(lines)


def skill_table(summaries: dict[str, list[dict]]) -> str:
    """Success minus the blind floor's on the same episodes, 95% intervals clustered by world."""
    lines = ["| planner | worlds | easy | medium | hard | all |", "|---|---|---|---|---|---|"]
    for planner, title in PLANNERS.items():
        if planner == FLOOR:
            continue
        for folder in SETS:
            by = _by(summaries.get(folder, []))
            if (planner, "all") not in by:
                continue
            cells = [_skill(by[(planner, d)]) if (planner, d) in by else "-" for d in (*DIFFICULTIES, "all")]
            lines.append(f"| {title} | {SETS[folder]} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def floor_table(folders: dict[str, tuple[list[dict], list[dict]]]) -> str:
    """How much blind speed solves, per difficulty and world set, and whether the measured
    difficulty of a world predicts its floor (Spearman over worlds)."""
    from scipy.stats import spearmanr

    lines = [
        "| worlds | floor: easy | medium | hard | worlds the floor never solves | Spearman (floor, corridor blocked) "
        "| Spearman (floor, crossings per minute) | Spearman (floor, obstacles) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for folder in ("paper60_barn", "original60_barn", "unseen_barn"):
        rows, summary = folders.get(folder, ([], []))
        by = _by(summary)
        if (FLOOR, "all") not in by:
            continue
        per_world: dict[str, list[float]] = defaultdict(list)
        for r in rows:
            if r["planner"] == FLOOR:
                per_world[r["world"]].append(float(r["outcome"] == "success"))
        worlds_path = RESULTS_DIR / folder / WORLDS
        measures = (
            {w["name"]: w for w in json.loads(worlds_path.read_text())["worlds"]} if worlds_path.is_file() else {}
        )
        names = sorted(n for n in per_world if n in measures and measures[n].get("measured"))
        floor = [sum(per_world[n]) / len(per_world[n]) for n in names]
        cells = []
        for key in ("corridor_blocked", "crossings_per_minute", "n_obstacles"):
            x = [measures[n]["measured"][key] if key != "n_obstacles" else measures[n]["n_obstacles"] for n in names]
            rho, p = spearmanr(x, floor) if len(names) > 2 else (math.nan, math.nan)
            cells.append(f"{rho:+.2f} (p = {p:.1g})")
        never = sum(v == 0 for v in floor)
        lines.append(
            f"| {SETS[folder]} | "
            + " | ".join(_ci(by[(FLOOR, d)]) if (FLOOR, d) in by else "-" for d in DIFFICULTIES)
            + f" | {never} of {len(names)} | "
            + " | ".join(cells)
            + " |"
        )
    return "\n".join(lines)


def td3_training() -> str:
    """The shipped TD3's run: command, time, steps, episodes, and its evaluations."""
    if not TD3_TRAINING.is_file():
        return "(no training record)"
    t = json.loads(TD3_TRAINING.read_text())
    cfg, evals = t["config"], t["evaluations"]
    best = evals[-1]
    return (
        f"{t['steps']:,} environment steps, {t['updates']:,} gradient updates, {t['episodes']:,} episodes, "
        f"{t['seconds'] / 60:.0f} min on this machine's 2 cores; {cfg['demos']} oracle demonstration episodes "
        f"({', '.join(f'{n} {k}' for k, n in sorted(t['demo_outcomes'].items()))}); evaluation on 30 episodes of the "
        f"training worlds with seeds of their own: success "
        f"{evals[0]['success']:.2f} after behaviour cloning, {best['success']:.2f} at the end."
    )


def headline_table(summaries: dict[str, list[dict]]) -> str:
    """The README's one table: the paper's bars, the floor and our planners on both world sets."""
    header = "| planner | paper: easy / medium / hard | paper60: easy | medium | hard | release's 60: hard |"
    lines = [header, "|---|---|---|---|---|---|"]
    paper60, original = _by(summaries.get("paper60_barn", [])), _by(summaries.get("original60_barn", []))
    for planner in (FLOOR, "dwa", "teb", "bc", "td3"):
        if (planner, "all") not in paper60:
            continue
        paper = " / ".join(f"{PAPER_FIG5[planner][d]:.2f}" for d in DIFFICULTIES) if planner in PAPER_FIG5 else "-"
        cells = [_ci(paper60[(planner, d)]) if (planner, d) in paper60 else "-" for d in DIFFICULTIES]
        hard = _ci(original[(planner, "hard")]) if (planner, "hard") in original else "-"
        lines.append(f"| {PLANNERS[planner]} | {paper} | " + " | ".join(cells) + f" | {hard} |")
    return "\n".join(lines)


def _gap_closed(by: dict, planner: str, difficulty: str) -> str:
    """How much of the distance from the floor to the exact-future oracle a rung closes."""
    keys = [(p, difficulty) for p in (planner, FLOOR, "oracle")]
    if not all(k in by for k in keys):
        return "-"
    rung, floor, top = (by[k]["success"] for k in keys)
    return f"{(rung - floor) / (top - floor):.0%}" if top > floor else "-"


def ladder_table(summaries: dict[str, list[dict]]) -> str:
    """Each rung's success per difficulty on both world sets, and the share of the floor-to-
    oracle distance it closes on the hard worlds."""
    paper60, original = _by(summaries.get("paper60_barn", [])), _by(summaries.get("original60_barn", []))
    lines = [
        "| rung | sees | paper60: easy | medium | hard | release's 60: easy | medium | hard "
        "| gap closed, hard: paper60 / release |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for planner, sees, what in LADDER:
        if (planner, "all") not in paper60 and (planner, "all") not in original:
            continue
        cells = [
            f"{by[(planner, d)]['success']:.2f}" if (planner, d) in by else "-"
            for by in (paper60, original)
            for d in DIFFICULTIES
        ]
        gap = f"{_gap_closed(paper60, planner, 'hard')} / {_gap_closed(original, planner, 'hard')}"
        lines.append(f"| {what} (`{planner}`) | {sees} | " + " | ".join(cells) + f" | {gap} |")
    return "\n".join(lines)


def tracking_quality(folders: dict[str, tuple[list[dict], list[dict]]]) -> str:
    """The tracker's quality against the truth, per planner that uses it and world set."""
    lines = [
        "| planner | worlds | difficulty | recall | precision | position error median / p95 [mm] "
        "| velocity error median / p95 [m/s] | identity switches per episode |",
        "|---|---|---|---|---|---|---|---|",
    ]
    names = {**SETS, **OTHER_SETS}
    for folder in ("paper60_barn", "original60_barn", *OTHER_SETS):
        for s in folders.get(folder, ([], []))[1]:
            if s.get("track_recall") is None or (folder in OTHER_SETS and s["difficulty"] != "all"):
                continue
            lines.append(
                f"| `{s['planner']}` | {names[folder]} | {s['difficulty']} | {s['track_recall']:.3f} "
                f"| {s['track_precision']:.3f} | {1000 * s['track_pos_err']:.1f} / {1000 * s['track_pos_err_p95']:.0f} "
                f"| {s['track_vel_err']:.3f} / {s['track_vel_err_p95']:.3f} | {s['track_id_switches']:.1f} |"
            )
    return "\n".join(lines)


def other_worlds(folders: dict[str, tuple[list[dict], list[dict]]], sets: dict[str, str] = OTHER_SETS) -> str:
    """Success and skill over the floor on the worlds beyond the paper's (`sets`)."""
    lines = [
        "| worlds | planner | episodes | easy | medium | hard | all | skill over floor, all |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for folder, title in sets.items():
        _, summary = folders.get(folder, ([], []))
        by = _by(summary)
        for planner in PLANNERS:
            if (planner, "all") not in by:
                continue
            cells = [f"{by[(planner, d)]['success']:.2f}" if (planner, d) in by else "-" for d in DIFFICULTIES]
            lines.append(
                f"| {title} | `{planner}` | {by[(planner, 'all')]['episodes']} | "
                + " | ".join(cells)
                + f" | {_ci(by[(planner, 'all')])} | {_skill(by[(planner, 'all')])} |"
            )
    return "\n".join(lines)


BLOCKS = {
    "headline": lambda f, s: headline_table(s),
    "other-worlds": lambda f, s: other_worlds(f),
    "tiers": lambda f, s: other_worlds(f, TIER_SETS),
    "ladder": lambda f, s: ladder_table(s),
    "tracking": lambda f, s: tracking_quality(f),
    "fig5": lambda f, s: fig5_table(s),
    "skill": lambda f, s: skill_table(s),
    "floor": lambda f, s: floor_table(f),
    "td3-training": lambda f, s: td3_training(),
    "generalisation": lambda f, s: generalisation_table(s),
    "dagger-training": lambda f, s: dagger_training(),
    "student-ablation": lambda f, s: student_ablation(),
    "set-student": lambda f, s: student_table("dagger_set"),
    "map-student": lambda f, s: student_table("dagger_map"),
    "dagger-curves": lambda f, s: dagger_curves(),
    "move-base": lambda f, s: move_base_table(f),
    "dwa-ablation": lambda f, s: ablation_table(f),
    "nav2": lambda f, s: nav2_table(f),
    "ros-speed": lambda f, s: ros_speed_table(_record("ros_speed/world137.json")),
    "warp-speed": lambda f, s: warp_speed_table(warp_speed_records()),
    "warp-agreement": lambda f, s: warp_agreement_table(warp_agreement_records()),
    "warp-student": lambda f, s: warp_student_table(),
    "certification": lambda f, s: certification_table(certified_sets()),
    "certified-ladder": lambda f, s: certified_ladder(f, certified_sets(), SETS, LADDER),
    "calibration": lambda f, s: calibration_table(),
    "leaderboard": lambda f, s: leaderboard_table(f, LEADERBOARD_SETS, STACK_GUESTS),
    "tier-ladder": lambda f, s: tier_ladder_table(f, TIER_SETS, LADDER),
    "trackers": lambda f, s: tracker_table(f, _ci, _skill),
    "perception-aims": lambda f, s: aims_tables(f, _ci),
    "teb-padding": lambda f, s: tracker_table(f, _ci, _skill, TEB_PADDING, "TEB plans against"),
    "tracker-validation": lambda f, s: validation_table(_record("tracker_validation/validation.json")),
    "perception-gap": lambda f, s: gap_table(_record("perception_gap/tier-combined.json"), wilson_interval),
    "collision-anatomy": lambda f, s: anatomy_table(_record("perception_gap/collisions_tier-combined.json")),
    "uncertainty-padding": lambda f, s: padding_table(_record("uncertainty_padding/validation.json"), wilson_interval),
}


PAGES = {
    README: ("headline", "ladder", "tier-ladder", "trackers", "certification", "generalisation", "nav2"),
    DOCS / "results.md": (
        "fig5",
        "skill",
        "floor",
        "ladder",
        "certification",
        "certified-ladder",
        "tracking",
        "trackers",
        "perception-aims",
        "other-worlds",
        "tiers",
        "generalisation",
    ),
    DOCS / "tutorials" / "training.md": ("td3-training", "dagger-training"),
    DOCS / "tutorials" / "ros.md": ("move-base", "dwa-ablation"),
    DOCS / "tutorials" / "ros2.md": ("nav2",),
    DOCS / "speed.md": ("ros-speed", "warp-speed"),
    DOCS / "concepts" / "warp.md": ("warp-student", "warp-agreement"),
    DOCS / "concepts" / "difficulty.md": ("calibration",),
    DOCS / "concepts" / "perception.md": (
        "tracker-validation",
        "perception-gap",
        "collision-anatomy",
        "uncertainty-padding",
        "teb-padding",
    ),
    DOCS / "concepts" / "learning.md": ("student-ablation", "dagger-curves", "set-student", "map-student"),
    DOCS / "leaderboard.md": ("leaderboard",),
}
"""Each page and the blocks it must hold (every block of BLOCKS is on some page)."""


def render(page: str, folders: dict, summaries: dict, blocks: tuple[str, ...] = tuple(BLOCKS)) -> str:
    for name in blocks:
        pattern = re.compile(rf"(<!-- results:{name} -->\n).*?(<!-- /results:{name} -->)", re.S)
        if not pattern.search(page):
            raise SystemExit(f"the page has no block <!-- results:{name} --> ... <!-- /results:{name} -->")
        text = BLOCKS[name](folders, summaries) + "\n"
        page = pattern.sub(lambda m, text=text: m.group(1) + text + m.group(2), page)
    return page


def draw(summaries: dict[str, list[dict]]) -> None:
    for folder, summary in summaries.items():
        if summary and folder != "unseen_barn":
            title = f"{SETS[folder]} worlds, barn protocol (95% Wilson intervals; the floor dashed)"
            plot_fig5(summary, FIGURES / f"fig5_{folder}.png", title=title)
            rungs = {planner for planner, _, _ in LADDER}
            ladder = [s for s in summary if s["planner"] in rungs]
            if ladder:
                title = f"the ladder from blind to all-knowing, {SETS[folder]} worlds (95% Wilson intervals)"
                plot_fig5(ladder, FIGURES / f"ladder_{folder}.png", title=title, order=tuple(p for p, _, _ in LADDER))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare only; exit 1 when a page differs")
    args = parser.parse_args(argv)
    folders, summaries = load_all()
    stale = []
    for page, blocks in PAGES.items():
        text = page.read_text()
        new = render(text, folders, summaries, blocks)
        if new != text:
            stale.append(page)
            if not args.check:
                page.write_text(new)
    names = ", ".join(str(p.relative_to(ROOT)) for p in stale)
    if args.check:
        if stale:
            print(f"the result tables of {names} differ from results/: run `make readme`", file=sys.stderr)
            return 1
        print("the result tables of the README and the documentation match results/")
        return 0
    draw(summaries)
    print(f"rewrote the result blocks of {names or 'no page'} and the figures in {FIGURES}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
