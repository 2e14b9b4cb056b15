"""A DAgger student whose every training episode ran on the Warp backend, swept on MuJoCo's
C engine on sets it never saw, beside the same recipe collected on the C engine and the
shipped student (issue 60, part 3).

Both students are trained by one reduced recipe (`RECIPE`: 5 iterations of 32 episodes,
the first student's teacher `oracle_present` and flat `mlp` encoder, no tracks), from the
same seed, so they saw the same procedural worlds and trials; only the engine that stepped
their episodes differs. A third run, the C recipe from another seed, says how far apart two
runs of the recipe fall anyway. The recipe is reduced because Warp's CPU device steps about 50
control steps a second on this machine's 2 cores (docs/speed.md): on a GPU, `--device cuda
--env-backend warp` runs the shipped recipe. Each is then swept on the C engine over the
whole of `paper60` and the release's 60 (10 trials), the sets whose committed sweeps hold
the shipped student's and the floor's rows for the same episodes.

    python benchmarks/warp_student.py

trains what is missing (about 15 minutes for the Warp run, 4 for each C run), then sweeps
(each resumes; about 2 minutes a sweep). It writes results/warp_student/RUN/ (the run's
config.json, train.log, training.json and policy.pt: the scratch run with its data is under
runs/) and the sweeps results/warp_student_RUN_FOLDER/ (each with the floor's rows); the table on
docs/concepts/warp.md (block `warp-student`) is generated from them. The release's 60 are
imported first from ../shared/reference when that is there (left out, and said, where not).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from collections import Counter
from pathlib import Path

from bench_command import ROOT, import_release, run_dynabarn
from tracker_tables import success_cell

from dynabarn.bench import DIFFICULTIES
from dynabarn.bench.results import RESULTS, is_row, read_results
from dynabarn.bench.stats import wilson_interval
from dynabarn.bench.summary import FLOOR

OUT = ROOT / "results" / "warp_student"
RUNS = {"warp": ("warp", 0), "c": ("c", 0), "c_seed1": ("c", 1)}
"""run -> (engine, seed): the Warp-collected student, its C twin (the same seed: the same
worlds, trials and initial weights) and the C recipe from another seed (how much two runs
of the recipe differ at all, for scale)."""
RECIPE = (
    "--iterations", "5", "--episodes", "32", "--max-steps", "300", "--updates", "1000",
    "--validation-episodes", "20", "--workers", "2", "--threads", "2", "--device", "cpu",
    "--profiles", "table1,release2022", "--teacher", "oracle_present", "--tracks", "0", "--encoder", "mlp",
    "--warp-envs", "16",
)  # fmt: skip
"""The reduced recipe, the same for both engines (`--env-backend` and `--seed` are added)."""
KEPT = ("config.json", "train.log", "training.json", "policy.pt")
"""What of a finished run is committed (its data and state stay in runs/)."""
SWEEPS = (
    # (set, its committed sweep, whose rows pair with these, title)
    ("paper60", "paper60_barn", "paper60"),
    ("imported_worlds", "original60_barn", "release's 60"),
)
TRIALS = 10


def train(name: str) -> int:
    """The recipe as run `name` (`RUNS`), unless its committed run is there already."""
    kept = OUT / name
    if (kept / "policy.pt").is_file():
        return 0
    run = ROOT / "runs" / f"warp_student_{name}"
    if run.exists():  # a run that stopped part-way: begin again (its iterations are not resumable mid-way)
        shutil.rmtree(run)
    engine, seed = RUNS[name]
    options = (*RECIPE, "--env-backend", engine, "--seed", str(seed))
    if run_dynabarn("train", "dagger", "--out", str(run.relative_to(ROOT)), *options):
        return 1
    kept.mkdir(parents=True, exist_ok=True)
    for name in KEPT:
        shutil.copyfile(run / name, kept / name)
    return 0


def sweep(name: str, world_set: str, folder: str) -> int:
    policy = (OUT / name / "policy.pt").relative_to(ROOT)
    out = (ROOT / "results" / f"warp_student_{name}_{folder}").relative_to(ROOT)
    return run_dynabarn(
        "bench", "--set", world_set, "--planner", "dagger", "--policy", str(policy),
        "--trials", str(TRIALS), "--jobs", "2", "--out", str(out),
    )  # fmt: skip


def _rows(folder: Path) -> list[dict]:
    """A sweep's result rows, as the summaries take them (`read_results`, `is_row`, no retries)."""
    return [r for r in read_results(folder / RESULTS) if is_row(r) and not r.get("retry")]


def _outcomes(rows: list[dict], planner: str) -> dict[tuple[str, int], str]:
    """(world file's name, seed) -> outcome, of the rows of `planner`."""
    return {(Path(r["world_file"]).name, r["seed"]): r["outcome"] for r in rows if r["planner"] == planner}


def table(results: Path = ROOT / "results") -> str:
    """Success [95% interval] per set and difficulty of both students, the shipped student
    and the floor over the same episodes, and each Warp-trained episode against its C twin."""
    head = " | ".join(f"{title}: {d}" for _, _, title in SWEEPS for d in DIFFICULTIES)
    lines = [f"| planner | {head} |", "|---|" + "---|" * len(SWEEPS) * len(DIFFICULTIES)]
    rows: dict[str, list[str]] = {}
    paired = {pair: {"won": 0, "lost": 0, "same": 0} for pair in (("warp", "c"), ("c_seed1", "c"))}
    titles = {
        "warp": "student, its episodes on Warp (CPU device)",
        "c": "student, the same recipe and seed on the C engine",
        "c_seed1": "student, the same recipe on the C engine, another seed",
        "dagger": "shipped student (`dagger`, full recipe)",
        FLOOR: f"blind floor (`{FLOOR}`)",
    }
    for _, committed, _ in SWEEPS:
        base = results / committed
        ours = {name: results / f"warp_student_{name}_{committed}" for name in RUNS}
        if not all((f / RESULTS).is_file() for f in (base, *ours.values())):
            for title in titles.values():
                rows.setdefault(title, []).extend(["-"] * len(DIFFICULTIES))
            continue
        base_rows = _rows(base)
        difficulty = {Path(r["world_file"]).name: r["difficulty"] for r in base_rows}
        outcomes = {name: _outcomes(_rows(ours[name]), "dagger") for name in RUNS}
        shared = set.intersection(*(set(outcomes[name]) for name in RUNS))
        outcomes |= {p: _outcomes(base_rows, p) for p in ("dagger", FLOOR)}
        for name, title in titles.items():
            for d in DIFFICULTIES:
                ends = Counter(outcomes[name][k] for k in shared if difficulty.get(k[0]) == d and k in outcomes[name])
                rows.setdefault(title, []).append(success_cell(ends, wilson_interval) if ends else "-")
        for (a, b), counts in paired.items():
            for k in shared:
                x, y = outcomes[a][k] == "success", outcomes[b][k] == "success"
                counts["won" if x and not y else "lost" if y and not x else "same"] += 1
    for title, cells in rows.items():
        lines.append(f"| {title} | " + " | ".join(cells) + " |")
    warp, seed = paired["warp", "c"], paired["c_seed1", "c"]
    lines.append("")
    lines.append(
        f"Paired over the same {sum(warp.values())} episodes against the C twin, the Warp-trained student succeeded "
        f"where the twin failed in {warp['won']} and failed where it succeeded in {warp['lost']}; the C recipe from "
        f"another seed, in {seed['won']} and {seed['lost']}."
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--table", action="store_true", help="print the table from results/ and run nothing")
    if parser.parse_args(argv).table:
        print(table())
        return 0
    for name in RUNS:
        if train(name):
            return 1
    released = import_release()
    for world_set, folder, _ in SWEEPS:
        if world_set == "imported_worlds" and not released:
            continue
        for name in RUNS:
            if sweep(name, world_set, folder):
                return 1
    print(table())
    return 0


if __name__ == "__main__":
    sys.exit(main())
