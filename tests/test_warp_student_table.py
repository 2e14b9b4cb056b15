"""`benchmarks/warp_student.py`'s table from hand-made rows with known answers: each run's
success over the episodes all of them share, the committed sweep's shipped student and
floor over those same episodes, and the paired counts."""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from warp_student import RUNS, table


def _rows(folder: Path, planner_successes: dict[str, list[bool]], difficulty: str = "hard") -> None:
    folder.mkdir(parents=True)
    with open(folder / "results.jsonl", "w") as f:
        for planner, successes in planner_successes.items():
            for seed, ok in enumerate(successes):
                row = {
                    "key": f"{planner}|{{}}|world_000.xml|barn|{seed}",
                    "planner": planner,
                    "world_file": "generated_worlds/world_000.xml",
                    "seed": seed,
                    "difficulty": difficulty,
                    "outcome": "success" if ok else "collision",
                }
                f.write(json.dumps(row) + "\n")
        f.write(json.dumps({"metadata": True}) + "\n")  # not a row: skipped


def test_the_table_counts_the_shared_episodes_and_pairs_them(tmp_path):
    t, f = True, False
    _rows(tmp_path / "paper60_barn", {"dagger": [t, t, t, f], "straight": [f, f, t, f]})
    runs = {"warp": [t, f, t, f], "c": [t, t, f, f], "c_seed1": [t, t, t, t]}
    assert set(runs) == set(RUNS)
    for name, successes in runs.items():
        # Each sweep has the floor's rows too: they must not be read as the student's.
        _rows(tmp_path / f"warp_student_{name}_paper60_barn", {"dagger": successes, "straight": [t, t, t, t]})
    text = table(tmp_path)
    lines = {line.split(" | ")[0].lstrip("| "): line for line in text.splitlines() if line.startswith("| ")}
    hard = 3  # the cells: planner, easy, medium, hard, then the release's 60 (absent: "-")
    assert lines["student, its episodes on Warp (CPU device)"].split(" | ")[hard].startswith("0.50 [")
    assert lines["student, the same recipe and seed on the C engine"].split(" | ")[hard].startswith("0.50 [")
    assert lines["student, the same recipe on the C engine, another seed"].split(" | ")[hard].startswith("1.00 [")
    assert lines["shipped student (`dagger`, full recipe)"].split(" | ")[hard].startswith("0.75 [")
    assert lines["blind floor (`straight`)"].split(" | ")[hard].startswith("0.25 [")
    assert lines["blind floor (`straight`)"].split(" | ")[1] == "-"  # no easy worlds
    # Warp against its C twin: won seed 2, lost seed 1; another seed against the twin: won 2 and 3.
    assert "same 4 episodes" in text and "failed in 1 and failed where it succeeded in 1" in text
    assert "another seed, in 2 and 0." in text


def test_a_missing_sweep_leaves_its_cells_empty(tmp_path):
    text = table(tmp_path)
    assert "0." not in text.split("Paired")[0] and "same 0 episodes" in text
