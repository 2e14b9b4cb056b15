"""One episode described once (`EpisodeSpec`) and run one way (`run_spec`): keys that keep
earlier results valid, settings that travel with the episode, a recording renamed only
when whole, and one line for a recording that cannot start."""

import json
import subprocess
import sys

import pytest

from dynabarn.errors import DynabarnError
from dynabarn.metrics import Outcome
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import MACHINE_FIELDS, read_recording
from dynabarn.runner import EpisodeSpec, RecordingFailed, run_spec
from dynabarn.sim import SimConfig, run_episode
from dynabarn.worldset import resolve_world

BARN = get_protocol("barn")


def test_a_default_episode_keeps_the_key_results_were_written_with():
    spec = EpisodeSpec.make(resolve_world(137), "dwa", BARN, config={"max_speed": 1.5}, seed=3)
    assert spec.key == 'dwa|{"max_speed": 1.5}|world_137.xml|barn|3'
    other = EpisodeSpec.make(
        resolve_world(137), "dwa", BARN, config={"max_speed": 1.5}, seed=3, sim=SimConfig(dt=0.0025)
    )
    assert other.key == spec.key + '|sim={"dt": 0.0025}' and other.sim_config.dt == 0.0025
    assert EpisodeSpec.from_dict(json.loads(json.dumps(other.to_dict()))) == other


def test_run_spec_is_run_episode_and_carries_its_settings(tmp_path):
    world = resolve_world(137)
    spec = EpisodeSpec.make(world, "dwa", BARN, seed=2)
    direct = run_episode(world, get_planner("dwa"), BARN, seed=2)
    clocks = {k: 0 for k in MACHINE_FIELDS}  # wall-clock figures differ run to run
    assert run_spec(spec).to_dict() | clocks == direct.to_dict() | clocks
    fine = run_spec(EpisodeSpec.make(world, "dwa", BARN, seed=2, sim=SimConfig(dt=0.0025, control_rate=20.0)))
    assert fine.n_ticks != direct.n_ticks  # 20 Hz: about twice the control periods
    assert fine.n_ticks == pytest.approx(2 * fine.sim_time * 10, abs=2)


def test_the_recording_appears_only_whole_and_is_read_back(tmp_path):
    rec = tmp_path / "ep.mcap"
    result = run_spec(EpisodeSpec.make(resolve_world(5), "straight", BARN), record_to=rec)
    assert rec.is_file() and not (tmp_path / "ep.mcap.part").exists()
    assert read_recording(rec).records["dynabarn.result"]["outcome"] == result.outcome.value
    assert result.outcome in (Outcome.SUCCESS, Outcome.COLLISION)


def test_a_recording_that_cannot_start_is_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    spec = EpisodeSpec.make(resolve_world(5), "straight", BARN)
    with pytest.raises(RecordingFailed, match="cannot record to") as info:
        run_spec(spec, record_to=blocker / "ep.mcap")  # a folder that is a file
    assert isinstance(info.value, DynabarnError) and "\n" not in str(info.value)


def test_dynabarn_run_dt_and_control_rate_reach_the_episode(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "dynabarn.cli",
            "run",
            "--world",
            "137",
            "--planner",
            "straight",
            "--no-log",
            "--dt",
            "0.0025",
            "--control-rate",
            "20",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    assert d["n_ticks"] == pytest.approx(d["sim_time"] * 20, abs=2)
