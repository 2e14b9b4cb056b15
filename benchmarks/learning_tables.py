"""The learned planners' blocks of the results pages: generalisation and the DAgger run.

Imported by `readme_results.py` (which owns the pages and their blocks); nothing here
runs an episode.
"""

from __future__ import annotations

import json
from pathlib import Path

from dynabarn.bench import DIFFICULTIES
from dynabarn.bench.stats import skill_text
from dynabarn.bench.summary import FLOOR
from dynabarn.learn.configs import completed_config

ROOT = Path(__file__).resolve().parents[1]
DAGGER_TRAINING = ROOT / "results" / "dagger_set_predictive_training" / "training.json"
"""The shipped student's run (`dagger_predictive.pt`)."""
FIRST_TRAINING = ROOT / "results" / "dagger_training" / "training.json"
"""The first student's run (`dagger.pt`, the default until issue 44)."""
GENERALISATION_SETS = {
    "original60_barn": "release's 60",
    "unseen_barn": "unseen 240",
    "paper60_barn": "paper60",
}
LEARNED = (
    (FLOOR, "-", "blind floor (`straight`)"),
    ("bc", "oracle demonstrations on the 300 worlds", "BC, paper-faithful (`bc`)"),
    ("td3", "paper60", "TD3, paper-faithful (`td3`)"),
    (
        "dagger",
        "procedural worlds only (the tiers' profiles too)",
        "DAgger student (`dagger`, shipped `dagger_predictive.pt`; departures: the scans' history by convolution, "
        "the tracker's tracks as a set, the measured velocity, a ReLU network classifying among the teacher's 42 "
        "commands, not Fig. 4's; taught by `predictive`)",
    ),
    ("predictive", "- (laser only)", "its teacher (`predictive`)"),
    ("oracle_present", "- (privileged)", "the privileged oracle (`oracle_present`; the earlier students' teacher)"),
)
"""(planner, what it trained on, row title), each read from the main sweeps of the sets."""
SEEN = {("td3", "paper60_barn"), ("bc", "paper60_barn"), ("bc", "unseen_barn")}
"""Cells where the policy trained on the worlds it is evaluated on (marked, not generalisation)."""


def _cell(by: dict, planner: str, d: str, *, skill: bool) -> str:
    s = by.get((planner, d))
    if s is None:
        return "-"
    if not skill:
        return f"{s['success']:.2f} [{s['success_lo']:.2f}, {s['success_hi']:.2f}]"
    if s.get("skill") is None:
        return "-"
    return skill_text(s)


def generalisation_table(summaries: dict[str, list[dict]]) -> str:
    """Success [95% interval] of the learned planners, the floor and the teacher on every
    evaluation set, then each one's skill over the floor; seen worlds marked with *."""
    out = []
    for skill in (False, True):
        what = "skill over the floor [95% CI]" if skill else "success [95% CI]"
        head = " | ".join(f"{name}: {d}" for name in GENERALISATION_SETS.values() for d in DIFFICULTIES)
        lines = [f"| {what} | trained on | {head} |", "|---|---|" + "---|" * 3 * len(GENERALISATION_SETS)]
        for planner, trained, title in LEARNED:
            if skill and planner == FLOOR:
                continue
            cells = []
            for folder in GENERALISATION_SETS:
                by = {(s["planner"], s["difficulty"]): s for s in summaries.get(folder, [])}
                mark = "\\*" if (planner, folder) in SEEN else ""
                cells += [
                    _cell(by, planner, d, skill=skill) + (mark if (planner, d) in by else "") for d in DIFFICULTIES
                ]
            if any(c != "-" for c in cells):
                lines.append(f"| {title} | {trained} | " + " | ".join(cells) + " |")
        out.append("\n".join(lines))
    return "\n\n".join(out)


def _student_rows(student: str, folder: str) -> list[dict]:
    """The rows of a student's own sweep of a set (results/STUDENT_FOLDER; its `dagger` rows
    named `student`, the floor's as they are), retries left out; [] where there is none."""
    from dynabarn.bench.results import read_results

    path = ROOT / "results" / f"{student}_{folder}" / "results.jsonl"
    rows = [r for r in read_results(path) if not r.get("retry")] if path.is_file() else []
    return [r | {"planner": student} if r["planner"] == "dagger" else r for r in rows]


def _curve(t: dict) -> str:
    return ", ".join(f"{e['validation']['success']:.2f}" for e in t["iterations"])


def _final(t: dict) -> float:
    return (t.get("final") or t["iterations"][-1])["validation"]["success"]


def _recipe(saved: dict) -> str:
    """What a DAgger run did, from its saved configuration (fields it predates as it ran them)."""
    cfg = completed_config(saved)
    worlds = ", ".join(f"`{p}`" for p in cfg["profile_sets"])
    return f"teacher `{cfg['teacher']}`, encoder `{cfg['encoder']}`, head `{cfg['head']}`, training worlds of {worlds}"


def dagger_training() -> str:
    """The shipped student's run: time, data, worlds, its validation curve, and the first
    student's run beside it."""
    if not DAGGER_TRAINING.is_file():
        return "(no training record)"
    t = json.loads(DAGGER_TRAINING.read_text())
    its = t["iterations"]
    last = its[-1]
    loss = "mean squared, normalised actions"
    if completed_config(t["config"])["head"] == "classify":
        loss = "cross-entropy of the teacher's command among its 42"
    final = t.get("final")
    tail = (
        f" The shipped weights: a final fit of {final['updates']:,} updates on all of it (learning rate falling to "
        f"0), imitation loss {final['loss']:.4f}, validation success {final['validation']['success']:.2f}."
        if final
        else " The shipped weights are the last iteration's (no final fit)."
    )
    recipe = _recipe(t["config"])
    text = (
        f"{recipe[0].upper()}{recipe[1:]}. {len(its)} iterations in {t['seconds'] / 60:.0f} min on this machine's "
        f"2 cores; "
        f"{last['dataset']:,} states labelled by the teacher, from {len(set(t['fingerprints'])):,} procedural "
        f"training worlds (none of them a shipped or imported one); the teacher's share of control "
        f"{its[0]['beta']:.2f} -> {last['beta']:.4f}; imitation loss ({loss}, on the "
        f"growing dataset of the student's own states) {its[0]['loss']:.4f} -> {last['loss']:.4f}; the student "
        f"alone on {last['validation']['episodes']} validation worlds, success per iteration: {_curve(t)}.{tail}"
    )
    if FIRST_TRAINING.is_file():
        r = json.loads(FIRST_TRAINING.read_text())
        text += (
            f" The first student (`dagger.pt`: {_recipe(r['config'])}, {len(r['iterations'])} iterations; "
            f"`{FIRST_TRAINING.parent.relative_to(ROOT)}`), on validation worlds of its own profiles: {_curve(r)}, "
            f"and {_final(r):.2f} after its final fit."
        )
    return text


STUDENT_VALIDATION = ROOT / "results" / "student_validation"
"""`benchmarks/student_validation.py`'s records: students and references on the same
procedural validation worlds (one JSON per group of profile sets)."""
ENTRY_TITLES = {
    "set_predictive": "`set`, taught by `predictive` (`dagger_predictive.pt`, the shipped `dagger`; 10 iterations)",
    "map": "the same recipe with the known map among the inputs (`dagger_map.pt`; 10 iterations)",
    "set": "`set` encoder, trained with the tiers' profiles too (10 iterations, no final fit)",
    "mlp_tiers": "`mlp`, the same data and seeds as `set` (5 iterations)",
    "set_5": "`set`, the same run after 5 iterations",
    "shipped": "first student (`dagger.pt`: `mlp`, trained on `table1`, `release2022`; 12 iterations)",
    "teacher": "the teacher, `oracle_present` (privileged)",
    "predictive": "`predictive` (laser only)",
    "floor": "blind floor (`straight`)",
}
"""Each validation entry's title, in the order the table lists them."""


def student_ablation() -> str:
    """Success [95% interval] of each entry on the validation worlds of each group."""
    records = sorted(STUDENT_VALIDATION.glob("*.json")) if STUDENT_VALIDATION.is_dir() else []
    if not records:
        return "(no student validation records yet: `python benchmarks/student_validation.py`)"
    lines = [
        "| validation worlds | entry | easy | medium | hard | all |",
        "|---|---|---|---|---|---|",
    ]
    # Records of the same worlds (a later run's entries beside an earlier run's) make one
    # group; an entry run again on them gives the same episodes, and is listed once.
    groups: dict[str, dict[str, dict]] = {}
    for path in records:
        record = json.loads(path.read_text())
        worlds = f"{record['worlds']} of {', '.join(f'`{p}`' for p in record['profile_sets'])}"
        for name, row in record["success"].items():
            groups.setdefault(worlds, {}).setdefault(name, row)
    order = list(ENTRY_TITLES)
    for worlds, rows in groups.items():
        for name in sorted(rows, key=lambda n: order.index(n) if n in order else len(order)):
            cells = [
                f"{c['rate']:.2f} [{c['interval'][0]:.2f}, {c['interval'][1]:.2f}]" if c["episodes"] else "-"
                for c in (rows[name][d] for d in (*DIFFICULTIES, "all"))
            ]
            lines.append(f"| {worlds} | {ENTRY_TITLES.get(name, name)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


SET_STUDENT_SETS = {
    "original60_barn": "release's 60",
    "paper60_barn": "paper60",
    "unseen_barn": "unseen 240",
    "tier_dense_barn": "`tier-dense`",
    "tier_fast_barn": "`tier-fast`",
    "tier_mixed_barn": "`tier-mixed`",
    "tier_combined_barn": "`tier-combined`",
}
"""Where the issue-44 students were run (results/PREFIX_FOLDER, PREFIX one of NEW_STUDENTS)
beside the sweep with the shipped student, its teacher and the floor (results/FOLDER),
compared on the same episodes."""
NEW_STUDENTS = {
    "dagger_set": "`set` student taught by `oracle_present` (`dagger_set.pt`)",
    "dagger_map": "`set` student taught by `predictive`, the known map among its inputs (`dagger_map.pt`)",
}
"""Each student's own sweeps (results/PREFIX_FOLDER) and its title: one table each."""
OTHER_ROWS = (
    ("dagger", "`dagger`: the `set` student taught by `predictive` (shipped `dagger_predictive.pt`)"),
    ("predictive", "`predictive` (the shipped student's teacher)"),
    ("oracle_present", "`oracle_present` (privileged; the `dagger_set.pt` student's teacher)"),
    (FLOOR, "blind floor"),
)


def student_table(prefix: str) -> str:
    """Success [95% interval] per difficulty of the student of `prefix` (`NEW_STUDENTS`)
    and, on the same worlds and trial seeds, the shipped student, both teachers and the
    floor."""
    rows = ((prefix, NEW_STUDENTS[prefix]), *OTHER_ROWS)
    lines = [
        "| worlds | trials | planner | " + " | ".join(DIFFICULTIES) + " | all |",
        "|---|---|---|" + "---|" * (len(DIFFICULTIES) + 1),
    ]
    for title, trials, by in student_summaries(prefix):
        for planner, name in rows:
            cells = [_cell(by, planner, d, skill=False) for d in (*DIFFICULTIES, "all")]
            if any(c != "-" for c in cells):
                lines.append(f"| {title} | {trials} | {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def student_summaries(prefix: str) -> list[tuple[str, int, dict[tuple[str, str], dict]]]:
    """Per set the student of `prefix` was swept on (`SET_STUDENT_SETS`' order): (the set's
    title, trials, summary rows by (planner, difficulty)) of the student and, on the same
    worlds and trial seeds, every planner of the set's committed sweep."""
    from dynabarn.bench.results import read_results
    from dynabarn.bench.summary import summarise

    out = []
    for folder, title in SET_STUDENT_SETS.items():
        ours = [r for r in _student_rows(prefix, folder) if r["planner"] == prefix]
        if not ours:
            continue
        episodes = {(r["world"], r["seed"]) for r in ours}
        rest = [r for r in read_results(ROOT / "results" / folder / "results.jsonl") if not r.get("retry")]
        same = [r for r in rest if (r.get("world"), r.get("seed")) in episodes]
        by = {(s["planner"], s["difficulty"]): s for s in summarise(ours + same)}
        out.append((title, len({r["seed"] for r in ours}), by))
    return out


DAGGER_RUNS = {
    "dagger_set_training": "`set`, teacher `oracle_present`",
    "dagger_set_predictive_training": "`set`, teacher `predictive`",
    "dagger_map_training": "`set`, teacher `predictive`, the map among the inputs",
    "dagger_mlp_tiers_training": "`mlp`, teacher `oracle_present`",
}
"""Training runs on the same split, seeds and profile sets (the tiers' too), compared
iteration by iteration: the encoder ablation and the teacher ablation (issue 44)."""


def dagger_curves() -> str:
    """Each run's validation success [95% interval] per iteration, on the same 60 validation
    worlds, with the teacher's share of control: the ablations at equal budget."""
    from dynabarn.bench.summary import wilson_interval

    runs = {}
    for folder, title in DAGGER_RUNS.items():
        path = ROOT / "results" / folder / "training.json"
        if path.is_file():
            runs[title] = json.loads(path.read_text())["iterations"]
    if not runs:
        return "(no training records)"
    depth = max(len(its) for its in runs.values())
    lines = [
        "| iteration | teacher's share | " + " | ".join(runs) + " |",
        "|---|---|" + "---|" * len(runs),
    ]
    for i in range(depth):
        cells, share = [], None
        for its in runs.values():
            if i >= len(its):
                cells.append("-")
                continue
            v, share = its[i]["validation"], its[i]["beta"]
            lo, hi = wilson_interval(round(v["success"] * v["episodes"]), v["episodes"])
            cells.append(f"{v['success']:.2f} [{lo:.2f}, {hi:.2f}]")
        lines.append(f"| {i} | {share:.3f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
