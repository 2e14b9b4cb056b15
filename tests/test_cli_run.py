"""`dynabarn-run` through its real entry point."""

import json
import subprocess
import sys

import pytest

from dynabarn.cli import run_main
from dynabarn.interfaces import Planner
from dynabarn.planners import register_planner
from dynabarn.recording import read_recording

REQUIRED_KEYS = {
    "world",
    "planner",
    "protocol",
    "seed",
    "outcome",
    "time",
    "path_length",
    "score",
    "spl",
    "min_clearance",
    "rtf",
}


def test_summary_line_and_default_recording(tmp_path, capsys):
    assert run_main(["--world", "0", "--planner", "straight", "--runs-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("world_000 | straight | barn | seed 0: SUCCESS")
    path = tmp_path / "world_000_straight_barn_s0.mcap"
    assert out[1] == f"recording: {path}"
    assert read_recording(path).result["outcome"] == "success"


def test_json_output(tmp_path, capsys):
    log = tmp_path / "r.mcap"
    assert run_main(["--world", "137", "--protocol", "paper2022", "--seed", "3", "--log", str(log), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d.keys() >= REQUIRED_KEYS
    assert d["protocol"] == "paper2022" and d["seed"] == 3 and d["recording"] == str(log)
    assert log.is_file()


def test_no_log_writes_nothing(tmp_path, capsys):
    assert run_main(["--world", "0", "--no-log", "--runs-dir", str(tmp_path)]) == 0
    assert not list(tmp_path.iterdir())
    assert "recording" not in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, first_line",
    [
        (["--world", "300"], "error: unknown world id 300"),
        (["--world", "nowhere.xml"], "error: world not found"),
        (["--world", "0", "--planner", "dwb"], "error: unknown planner 'dwb'; available:"),
        (["--world", "0", "--protocol", "barn2"], "error: unknown protocol 'barn2'"),
        (["--world", "0", "--planner-config", "speed"], "error: bad --planner-config item"),
        (["--world", "0", "--planner-config", "nope=1"], "error: planner 'straight': bad configuration"),
        (["--world", "0", "--dt", "0.05"], "dynabarn-run: error: argument --dt: 0.05 is not in [0.0001, 0.01]"),
    ],
)
def test_bad_input_one_line_nonzero(argv, first_line, capsys, tmp_path):
    try:
        code = run_main([*argv, "--runs-dir", str(tmp_path)])
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith(first_line), err
    assert err.count("\n") == 1


def test_malformed_world_file(tmp_path, capsys):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><custom><text name='dynabarn_world' data='{not json'/></custom></mujoco>")
    assert run_main(["--world", str(bad), "--no-log"]) == 2
    assert "not valid JSON" in capsys.readouterr().err


class Boom(Planner):
    name = "boom"

    def act(self, obs):
        raise RuntimeError("kaput")


class CtrlC(Planner):
    name = "ctrl_c"

    def act(self, obs):
        if obs.time >= 0.3:
            raise KeyboardInterrupt
        return 0.5, 0.0


def test_planner_error_exits_nonzero_and_keeps_recording(tmp_path, capsys):
    register_planner(Boom, name="boom")
    log = tmp_path / "b.mcap"
    assert run_main(["--world", "0", "--planner", "boom", "--log", str(log)]) == 1
    captured = capsys.readouterr()
    assert "ERROR" in captured.out and "error: planner raised RuntimeError: kaput" in captured.err
    assert read_recording(log).result["outcome"] == "error"


def test_ctrl_c_exits_130_with_complete_recording(tmp_path, capsys):
    register_planner(CtrlC, name="ctrl_c")
    log = tmp_path / "c.mcap"
    assert run_main(["--world", "0", "--planner", "ctrl_c", "--log", str(log)]) == 130
    assert "recording kept" in capsys.readouterr().err
    rec = read_recording(log)
    assert not rec.truncated and rec.result["reason"] == "interrupted"


def test_console_script_no_traceback(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "dynabarn.cli", "run", "--world", "0", "--planner", "nope"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr


def test_help_lists_every_option_with_default(capsys):
    with pytest.raises(SystemExit):
        run_main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    for opt in ("--world", "--planner", "--protocol", "--seed", "--log", "--no-log", "--json", "--dt"):
        assert opt in out
    assert "(default: barn)" in out and "(default: 0)" in out


def test_shipped_presets_load_into_their_planners():
    from dynabarn.cli.common import planner_config as _planner_config
    from dynabarn.planners import get_planner, planner_presets

    assert "dwa_barn_challenge" in planner_presets()
    for name in planner_presets():
        cfg = _planner_config(name)
        assert cfg and not any(k.startswith("_") for k in cfg)
        # A preset named after a planner is its; a tracker's (it sets only `tracker`) is every
        # tracking planner's.
        owners = ("predictive", "dwa", "teb") if set(cfg) == {"tracker"} else (name.split("_")[0],)
        for owner in owners:
            config = get_planner(owner, **cfg).config()
            for key, value in cfg.items():  # every preset value reaches the planner's configuration
                section, _, field = key.rpartition(".")
                got = config[section][field] if section else config[key]
                if isinstance(value, dict):  # a nested section: the values it names
                    got = {k: got[k] for k in value}
                assert got == value
    # The BARN Challenge's DWA never samples standing still (TrajectoryPlannerROS min_vel_x 0.1).
    barn = _planner_config("dwa_barn_challenge")
    assert (barn["min_vel_x"], barn["max_vel_x"], barn["sim_time"]) == (0.1, 0.5, 2.0)


def test_the_same_episode_in_two_processes_gives_the_same_row_but_for_timings(tmp_path):
    """Every field of `--json`, the machine block included (its BLAS libraries came in
    either order from process to process), but the wall-clock ones."""
    timings = {"planner_ms_mean", "planner_ms_p95", "rtf", "wall_time"}
    rows = []
    for _ in range(2):
        proc = subprocess.run(
            [sys.executable, "-m", "dynabarn", "run", "--world", "137", "--planner", "straight", "--seed", "3",
             "--json", "--no-log"],
            capture_output=True, text=True, cwd=tmp_path, timeout=300,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        rows.append(json.loads(proc.stdout))
    first, second = ({k: v for k, v in row.items() if k not in timings} for row in rows)
    assert set(rows[0]) - set(first) == timings  # the only fields left out
    assert first["machine"]["blas"], "threadpoolctl sees numpy's and scipy's BLAS"
    assert first == second


def test_json_keys_in_help_are_the_printed_keys(tmp_path, capsys):
    """`--help` lists the keys of `--json` (read off EpisodeResult): exactly those printed."""
    from dynabarn.cli.common import result_keys

    assert run_main(["--world", "0", "--planner", "stop", "--no-log", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert list(printed) == sorted(result_keys())
    assert run_main(["--world", "0", "--planner", "predictive", "--no-log", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert list(printed) == sorted(result_keys(tracked=True))
    assert set(printed["tracking"]) >= {"recall", "precision", "position_error_median", "id_switches"}
    with pytest.raises(SystemExit):
        run_main(["--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "its keys: " + ", ".join(result_keys()) in help_text
