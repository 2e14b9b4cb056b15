"""Any planner from the command line (issue 56): `--planner FILE.py:CLASS` and
`--planner MODULE:CLASS`, unpackaged, in dynabarn-run and dynabarn-bench; rows record the
code's identity, and --verify runs such rows only with the same code named by the person
verifying. `run_sweep` from Python writes the whole folder."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from dynabarn.cli.bench import bench_main
from dynabarn.cli.run import run_main
from tests.test_fuzz import one_clear_line

CAUTIOUS = """
import numpy as np

from dynabarn import Planner


class Cautious(Planner):
    name = "cautious"

    def __init__(self, half_width: float = 0.45):
        self.half_width = half_width

    def reset(self, info):
        self.cos, self.sin = np.cos(info.laser_angles), np.sin(info.laser_angles)

    def act(self, obs):
        x, y = obs.scan * self.cos, obs.scan * self.sin
        ahead = (x > 0) & (np.abs(y) < self.half_width)
        gap = float(x[ahead].min()) if ahead.any() else np.inf
        gx, gy = obs.goal_in_robot
        return 2.0 * float(np.clip((gap - 0.6) / 3.0, 0.0, 1.0)), float(np.clip(2.0 * np.arctan2(gy, gx), -3, 3))

    def config(self):
        return {"half_width": self.half_width}


class NotAPlanner:
    pass
"""
SWEEP = ["--set", "paper60", "--worlds", "0,100", "--trials", "1", "--no-floor"]


@pytest.fixture(autouse=True)
def _forget_code_planners():
    """Each test starts as a fresh command would: no planner from code loaded."""
    from dynabarn.planners.from_code import LOADED
    from dynabarn.planners.registry import PLANNERS

    yield
    for name in list(LOADED):
        PLANNERS.pop(name, None)
        del LOADED[name]


@pytest.fixture()
def code(tmp_path, monkeypatch) -> Path:
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "cautious_planner.py").write_text(CAUTIOUS)
    monkeypatch.chdir(folder)
    return folder / "cautious_planner.py"


def test_a_file_planner_runs_in_a_sweep_across_workers_and_verifies(code, tmp_path, capsys):
    out = tmp_path / "sweep"
    spec = f"{code}:Cautious"
    assert bench_main(["--planner", spec, *SWEEP, "--jobs", "2", "--out", str(out)]) == 0
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert {r["planner"] for r in rows} == {"cautious_planner.py:Cautious"} and len(rows) == 2
    sha = __import__("hashlib").sha256(code.read_bytes()).hexdigest()
    assert all(r["planner_code"] == {"file": "cautious_planner.py", "sha256": sha, "object": "Cautious"} for r in rows)
    assert str(code.parent) not in (out / "results.jsonl").read_text()  # the file's name only, not its folder
    capsys.readouterr()
    # Without the code named: not checked (exit 3), and what to name.
    assert bench_main(["--verify", str(out), "--sample", "all"]) == 3
    assert "--planner PATH/cautious_planner.py:Cautious" in capsys.readouterr().out
    # Named: re-run in workers, identical.
    assert bench_main(["--verify", str(out), "--sample", "all", "--jobs", "2", "--planner", spec]) == 0
    assert "2 rows re-run: 2 identical" in capsys.readouterr().out
    # Other bytes under the same name: refused in one line.
    other = tmp_path / "other" / "cautious_planner.py"
    other.parent.mkdir()
    other.write_text(CAUTIOUS + "\n# edited\n")
    from dynabarn.planners.from_code import LOADED
    from dynabarn.planners.registry import PLANNERS

    PLANNERS.pop("cautious_planner.py:Cautious"), LOADED.pop("cautious_planner.py:Cautious")  # a new command
    line = one_clear_line("bench", ["--verify", str(out), "--planner", f"{other}:Cautious"])
    assert "is not the file the row ran" in line


def test_a_module_in_the_current_folder_runs_in_dynabarn_run(code, capsys):
    assert run_main(["--planner", "cautious_planner:Cautious", "--world", "0", "--no-log"]) == 0
    assert "cautious_planner:Cautious" in capsys.readouterr().out


@pytest.mark.parametrize(
    "spec, message",
    [
        ("cautious_planner.py:NotAPlanner", "not a subclass of dynabarn.interfaces.Planner"),
        ("cautious_planner.py:Missing", "has no Missing"),
        ("nowhere.py:Cautious", "is not a .py file"),
        ("no_such_module_here:Cautious", "No module named"),
        ("broken.py:Cautious", "raised ZeroDivisionError"),
    ],
)
def test_code_that_is_not_a_planner_is_one_line(spec, message, code):
    (code.parent / "broken.py").write_text("1 / 0\n")
    line = one_clear_line("run", ["--planner", spec, "--world", "0"])
    assert message in line, line


def test_verify_names_only_code_planners(code, tmp_path):
    out = tmp_path / "s"
    assert bench_main(["--planner", "stop", *SWEEP, "--out", str(out)]) == 0
    assert "names only planners from code" in one_clear_line("bench", ["--verify", str(out), "--planner", "dwa"])


def test_run_sweep_from_python_writes_the_whole_folder(code, tmp_path):
    from dynabarn import bench, get_protocol, worldset
    from dynabarn.planners import planner_spec

    name, _, _ = planner_spec(f"{code}:Cautious")
    worlds = worldset.world_set("paper60", [0])
    jobs = bench.make_jobs([("straight", {}), (name, {})], worlds, get_protocol("barn"), trials=1)
    out = tmp_path / "py"
    report = bench.run_sweep(jobs, out)
    for name in ("results.jsonl", "metadata.json", "worlds.json", "summary.md", "fig5.png", "report.html"):
        assert (out / name).is_file(), name
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["invocations"][0]["arguments"] == {"from": "dynabarn.bench.run_sweep"}
    assert {s["planner"] for s in report.summary} == {"straight", "cautious_planner.py:Cautious"}
    shutil.rmtree(out)
    bench.run_sweep(jobs, out, folder=False)
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["results.jsonl"]
