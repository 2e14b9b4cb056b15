"""dynabarn-bench: correctness against individual runs, resuming, errors, the Ray backend."""

import json

import pytest

from dynabarn import bench, worldset
from dynabarn.cli import bench_main
from dynabarn.interfaces import Planner
from dynabarn.planners import get_planner, register_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import MACHINE_FIELDS
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world
from tests.conftest import require

WALL_CLOCK = set(MACHINE_FIELDS)
BARN = get_protocol("barn")


def _strip(row: dict) -> dict:
    return {k: v for k, v in row.items() if k not in WALL_CLOCK}


def _jobs(planner="straight", worlds="0,1,200", trials=2):
    return bench.make_jobs([(planner, {})], worldset.world_set("dynabarn300", worldset.parse_ids(worlds)), BARN, trials)


def test_wilson_interval_known_values():
    lo, hi = bench.wilson_interval(8, 10)
    assert lo == pytest.approx(0.4902, abs=1e-3) and hi == pytest.approx(0.9433, abs=1e-3)
    assert bench.wilson_interval(0, 20)[0] == 0.0
    assert worldset.parse_ids("0,5,100-102") == [0, 5, 100, 101, 102]


def test_sweep_rows_and_summary_match_individual_runs(tmp_path):
    jobs = _jobs()
    report = bench.run_sweep(jobs, tmp_path, n_workers=2)
    assert report.ran == 6 and report.errors == 0
    rows = bench.read_results(tmp_path / bench.RESULTS)
    assert len(rows) == 6
    by_key = {r["key"]: r for r in rows}
    for job in jobs:
        direct = run_episode(resolve_world(job.world_id), get_planner("straight"), BARN, seed=job.spec.seed).to_dict()
        row = by_key[job.key]
        assert {k: row[k] for k in _strip(direct)} == _strip(direct)
        assert row["versions"]["mujoco"] and len(row["world_sha256"]) == 64
    summary = {(s["planner"], s["difficulty"]): s for s in bench.summarise(rows)}
    easy = [r for r in rows if r["difficulty"] == "easy"]
    assert summary[("straight", "easy")]["episodes"] == len(easy) == 4
    assert summary[("straight", "easy")]["success"] == sum(r["outcome"] == "success" for r in easy) / 4
    assert summary[("straight", "all")]["episodes"] == 6


def test_interrupted_sweep_resumes_to_the_same_results(tmp_path):
    jobs = _jobs(trials=3)
    full = bench.run_sweep(jobs, tmp_path / "full", n_workers=1)

    def interrupt_after(n):
        def progress(stream, total):
            for i, row in enumerate(stream):
                if i == n:
                    raise KeyboardInterrupt
                yield row

        return progress

    with pytest.raises(KeyboardInterrupt):
        bench.run_sweep(jobs, tmp_path / "cut", n_workers=1, progress=interrupt_after(4))
    assert len(bench.read_results(tmp_path / "cut" / bench.RESULTS)) == 4
    # A crash mid-write leaves a torn line: it is ignored and rewritten.
    with (tmp_path / "cut" / bench.RESULTS).open("a") as f:
        f.write('{"key": "half a li')
    resumed = bench.run_sweep(jobs, tmp_path / "cut", n_workers=2)
    assert resumed.skipped == 4 and resumed.ran == len(jobs) - 4
    a = sorted((_strip(r) for r in full.rows), key=lambda r: r["key"])
    b = sorted((_strip(r) for r in resumed.rows), key=lambda r: r["key"])
    assert a == b


class Explodes(Planner):
    name = "explodes"

    def act(self, obs):
        raise ZeroDivisionError("nope")


def test_error_episodes_are_recorded_and_the_sweep_goes_on(tmp_path):
    register_planner(Explodes, name="explodes")
    jobs = bench.make_jobs([("explodes", {}), ("straight", {})], worldset.world_set("dynabarn300", [0]), BARN, 1)
    report = bench.run_sweep(jobs, tmp_path, n_workers=1)
    rows = {r["planner"]: r for r in report.rows}
    assert rows["explodes"]["outcome"] == "error" and "ZeroDivisionError" in rows["explodes"]["reason"]
    assert rows["straight"]["outcome"] == "success"


def test_cli_writes_summary_files_and_records_failures(tmp_path, capsys):
    out = tmp_path / "b"
    argv = [
        "--planner",
        "straight",
        "--worlds",
        "0,200",
        "--trials",
        "2",
        "--jobs",
        "2",
        "--record",
        "failures",
        "--out",
        str(out),
    ]
    assert bench_main(argv) == 0
    text = capsys.readouterr().out
    assert "straight" in text and "success [95% CI]" in text
    for name in ("results.jsonl", "summary.csv", "summary.md", "fig5.png", "metadata.json"):
        assert (out / name).is_file(), name
    rows = bench.read_results(out / "results.jsonl")
    failures = [r for r in rows if r["outcome"] != "success"]
    assert failures and all((out / "recordings").joinpath(r["recording"].split("/")[-1]).is_file() for r in failures)
    assert not any("recording" in r for r in rows if r["outcome"] == "success")
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["planners"] == ["straight"] and meta["episodes"] == 4
    # Same command again: nothing to do.
    assert bench_main(argv) == 0
    assert "0 episodes run, 4 already done" in capsys.readouterr().out
    # Another protocol into the same folder is refused without --force.
    assert bench_main([*argv, "--protocol", "paper2022"]) == 2
    assert "different sweep" in capsys.readouterr().err
    # So are other simulation settings: their episodes would share the planner's rows.
    assert bench_main([*argv, "--dt", "0.0025", "--control-rate", "20"]) == 2
    assert "different sweep (sim differs)" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--planner", "nope"], "unknown planner"),
        (["--set", "nowhere"], "unknown world set"),
        (["--worlds", "1-x"], "bad --worlds item"),
        (["--worlds", "400"], "not in set"),
    ],
)
def test_bad_input(tmp_path, capsys, argv, message):
    assert bench_main([*argv, "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.slow
def test_ray_backend_gives_identical_results(tmp_path):
    require("ray", "ray")
    jobs = _jobs(worlds="0,150", trials=2)
    local = bench.run_sweep(jobs, tmp_path / "local", n_workers=2)
    ray = bench.run_sweep(jobs, tmp_path / "ray", backend="ray", n_workers=2)
    a = sorted((_strip(r) for r in local.rows), key=lambda r: r["key"])
    b = sorted((_strip(r) for r in ray.rows), key=lambda r: r["key"])
    assert a == b and len(a) == 4


def test_wilson_interval_contains_the_rate():
    for n in (1, 7, 20, 200):
        for k in (0, n // 2, n):
            lo, hi = bench.wilson_interval(k, n)
            assert lo <= k / n <= hi


def test_the_blind_floor_runs_beside_every_planner_with_skill_over_it(tmp_path, capsys):
    """Without --no-floor, `straight` runs on the same worlds and seeds; the summary gives
    each planner's success minus the floor's on the same episodes, with an interval."""
    out = tmp_path / "f"
    argv = ["--planner", "stop", "--worlds", "0,1,200", "--trials", "2", "--jobs", "2", "--out", str(out)]
    assert bench_main(argv) == 0
    text = capsys.readouterr().out
    rows = bench.read_results(out / "results.jsonl")
    assert sorted({r["planner"] for r in rows}) == ["stop", "straight"]
    floor = {(r["world"], r["seed"]): r["outcome"] == "success" for r in rows if r["planner"] == "straight"}
    assert len(floor) == 6
    summary = {(s["planner"], s["difficulty"]): s for s in bench.summarise(rows)}
    stop = summary[("stop", "all")]
    # `stop` never reaches the goal: its skill is minus the floor's success, exactly.
    assert stop["success"] == 0.0 and stop["floor"] == pytest.approx(sum(floor.values()) / 6)
    assert stop["skill"] == pytest.approx(-stop["floor"])
    assert stop["skill_lo"] <= stop["skill"] <= stop["skill_hi"]
    assert summary[("straight", "all")]["skill"] is None
    assert "skill over floor" in text and "skill over floor" in (out / "summary.md").read_text()
    # worlds.json: the sweep's worlds with their measured difficulty.
    worlds = json.loads((out / "worlds.json").read_text())["worlds"]
    assert [w["id"] for w in worlds] == [0, 1, 200] and all("corridor_blocked" in w["measured"] for w in worlds)
    # --no-floor runs only what was asked.
    assert (
        bench_main(["--planner", "stop", "--worlds", "0", "--trials", "1", "--no-floor", "--out", str(tmp_path / "n")])
        == 0
    )
    assert {r["planner"] for r in bench.read_results(tmp_path / "n" / "results.jsonl")} == {"stop"}


def test_skill_interval_is_clustered_by_world():
    """Ten trials of one world are not ten independent worlds: with every win in one world,
    the interval is wider than with the same wins spread over worlds."""
    from dynabarn.bench.summary import FLOOR, skill_over_floor

    def rows(planner, successes, per_world):
        return [
            {
                "planner": planner,
                "world": f"w{i // per_world}",
                "seed": i % per_world,
                "outcome": "success" if s else "x",
            }
            for i, s in enumerate(successes)
        ]

    wins = [1] * 10 + [0] * 30
    widths = {}
    for per_world in (10, 1):
        r = skill_over_floor(rows("p", wins, per_world), rows(FLOOR, [0] * 40, per_world))
        assert r["skill"] == pytest.approx(0.25) and r["skill_lo"] < 0.25 < r["skill_hi"]
        widths[per_world] = r["skill_hi"] - r["skill_lo"]
    assert widths[10] > 0.5 > widths[1]


def test_presets_run_as_their_own_rows(tmp_path, capsys):
    """NAME@PRESET: the preset's parameters, a row label of its own, the paper's value of NAME."""
    out = tmp_path / "p"
    argv = [
        "--planner",
        "dwa,dwa@dwa_dynabarn_authors",
        "--worlds",
        "0",
        "--trials",
        "1",
        "--no-floor",
        "--out",
        str(out),
    ]
    assert bench_main(argv) == 0
    rows = {r["planner"]: r for r in bench.read_results(out / "results.jsonl")}
    assert set(rows) == {"dwa", "dwa@dwa_dynabarn_authors"}
    authors = rows["dwa@dwa_dynabarn_authors"]["planner_config"]
    assert authors["max_vel_x"] == 2.0 and authors["vx_samples"] == 12 and authors["costmap"]["resolution"] == 0.05
    assert rows["dwa"]["planner_config"]["max_vel_x"] == 2.0
    summary = {
        (s["planner"], s["difficulty"]): s for s in bench.summarise(list(rows.values()), bench.paper_worlds(out))
    }
    assert summary[("dwa@dwa_dynabarn_authors", "easy")]["paper"] == 0.78
    assert bench_main(["--planner", "dwa@nope", "--worlds", "0", "--out", str(tmp_path / "x")]) == 2
    assert "unknown planner preset" in capsys.readouterr().err


def test_fig5_draws_only_the_difficulties_that_ran(tmp_path):
    """A sweep of hard worlds only: one group in the figure, not two empty ones beside it."""
    from dynabarn.bench.summary import FLOOR, fig5_groups, plot_fig5

    def row(planner, difficulty, success):
        return {"planner": planner, "difficulty": difficulty, "success": success, "success_lo": success - 0.1,
                "success_hi": success + 0.1, "paper": None}  # fmt: skip

    hard_only = [row("dwa", "hard", 0.3), row(FLOOR, "hard", 0.1), row("dwa", "all", 0.3), row(FLOOR, "all", 0.1)]
    assert fig5_groups(hard_only) == ["hard"]
    assert fig5_groups([*hard_only, row("dwa", "easy", 0.8)]) == ["easy", "hard"]
    path = plot_fig5(hard_only, tmp_path / "fig5.png")
    assert path.stat().st_size > 1000


def test_summary_marks_privileged_planners_and_summarises_tracking():
    """The oracles are marked privileged; a planner's tracking columns are the medians of its
    episodes' values (identity switches: the mean), and None for planners that do not track."""
    from dynabarn.bench.summary import format_table, tracking_table

    def row(planner, world, outcome, tracking=None):
        r = {"planner": planner, "difficulty": "hard", "world": world, "seed": 0, "outcome": outcome}
        return r | ({"tracking": tracking} if tracking else {})

    def quality(recall, pos, switches):
        return {
            "recall": recall,
            "precision": 1.0,
            "position_error_median": pos,
            "position_error_p95": 10 * pos,
            "velocity_error_median": 0.01,
            "velocity_error_p95": 0.3,
            "id_switches": switches,
            "ticks": 100,
        }

    rows = [row("straight", w, "collision") for w in ("a", "b", "c")]
    rows += [row("oracle", w, "success") for w in ("a", "b", "c")]
    rows += [
        row("predictive", "a", "success", quality(0.90, 0.001, 2)),
        row("predictive", "b", "success", quality(0.99, 0.003, 4)),
        row("predictive", "c", "collision", quality(0.95, 0.100, 9)),
    ]
    by = {(s["planner"], s["difficulty"]): s for s in bench.summarise(rows)}
    assert by[("oracle", "hard")]["privileged"] and not by[("predictive", "hard")]["privileged"]
    assert by[("oracle", "hard")]["track_recall"] is None
    p = by[("predictive", "hard")]
    assert p["track_recall"] == 0.95 and p["track_pos_err"] == 0.003 and p["track_pos_err_p95"] == 0.03
    assert p["track_id_switches"] == 5.0
    table = format_table(list(by.values()))
    assert "oracle (privileged)" in table and "predictive (privileged)" not in table
    assert "0.950" in tracking_table([p])


def test_the_sweep_speed_benchmark_times_every_shipped_planner(monkeypatch):
    """`benchmarks/sweep_speed.py` (make bench's sweep rows): each shipped planner and preset
    builds, and a short sweep is timed from its own results (episodes, simulated seconds,
    the planner's time per call)."""
    import sys
    from pathlib import Path

    from dynabarn.planners import planner_spec

    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from sweep_speed import SHIPPED, sweep_speed

    for planner in SHIPPED:
        name, config, _ = planner_spec(planner)
        get_planner(name, **config)
    speed = sweep_speed("dwa", jobs=1, ids=[0, 150])
    assert speed.episodes == 2 and speed.sim_s > 1.0 and speed.wall_s > 0.0
    assert speed.real_time_factor == speed.sim_s / speed.wall_s and 0.05 < speed.planner_ms < 1000.0
    assert "sweep_speed" in sys.modules
