"""`dynabarn-bench --compare`: known answers on made rows, and two real folders."""

from __future__ import annotations

import json

import pytest

from dynabarn.bench.compare import compare
from dynabarn.cli.bench import bench_main
from tests.test_fuzz import one_clear_line


def _rows(planner: str, outcomes: list[list[int]], difficulty: str = "hard") -> list[dict]:
    return [
        {
            "key": f"{planner}|{{}}|world_{w:03d}.xml|barn|{s}",
            "planner": planner,
            "world": f"world_{w:03d}",
            "world_sha256": f"sha{w}",
            "seed": s,
            "difficulty": difficulty,
            "outcome": "success" if o else "collision",
        }
        for w, trials in enumerate(outcomes)
        for s, o in enumerate(trials)
    ]


def test_all_success_against_all_failure_on_three_worlds():
    result = compare(_rows("a", [[1] * 10] * 3), _rows("b", [[0] * 10] * 3))
    every = result["rows"][-1]
    assert every["difficulty"] == "all" and result["shared"] == 30
    assert every["difference"] == 1.0 and every["hi"] == 1.0 and -0.2 < every["lo"] < 0.0
    assert [d["world"] for d in every["disagree"]] == ["world_000", "world_001", "world_002"]
    assert every["text"].endswith("\u2020")  # 3 worlds: marked


def test_identical_planners_agree_everywhere_with_an_interval_about_zero():
    trials = [[1, 0, 1, 1], [0, 0, 1, 0], [1, 1, 1, 1]]
    every = compare(_rows("a", trials), _rows("b", trials))["rows"][-1]
    assert every["difference"] == 0.0 and every["disagree"] == []
    assert every["lo"] < 0 < every["hi"] and every["lo"] == pytest.approx(-every["hi"])


def test_only_the_same_episode_pairs():
    """Another world file (sha256) or a seed only one side ran is left out, and counted."""
    a = _rows("a", [[1, 1], [1, 1]])
    b = _rows("b", [[0, 0, 0], [0, 0, 0]])
    b[0]["world_sha256"] = "other bytes"
    result = compare(a, b)
    assert result["shared"] == 3 and result["a_only"] == 1 and result["b_only"] == 3


def test_compare_two_folders_in_the_terminal_and_as_a_report(tmp_path, capsys):
    one = ["--set", "paper60", "--worlds", "0,200", "--trials", "2", "--jobs", "1"]
    a, b = tmp_path / "a", tmp_path / "b"
    assert bench_main(["--planner", "stop", *one, "--out", str(a)]) == 0
    assert bench_main(["--planner", "dwa", "--no-floor", *one, "--out", str(b)]) == 0
    capsys.readouterr()
    # `a` holds stop and the floor: the floor against dwa, named.
    assert bench_main(["--compare", str(a), str(b), "--planner", "straight,dwa", "--out", str(tmp_path / "c")]) == 0
    out = capsys.readouterr().out
    assert "A = straight (a), B = dwa (b): 4 shared episodes" in out
    saved = json.loads((tmp_path / "c" / "comparison.json").read_text())
    assert saved["shared"] == 4 and saved["rows"][-1]["difficulty"] == "all"
    page = (tmp_path / "c" / "report.html").read_text()
    assert "A: straight (a) against B: dwa (b)" in page
    # One folder with itself needs two planners; a planner it lacks is one line.
    assert "name its two planners" in one_clear_line("bench", ["--compare", str(a), str(a)])
    assert "no rows of planner 'teb'" in one_clear_line("bench", ["--compare", str(a), str(b), "--planner", "teb,dwa"])
    assert "not for --compare" in one_clear_line("bench", ["--compare", str(a), str(b), "--trials", "3"])
