"""One episode described once (`EpisodeSpec`) and run one way (`run_spec`): keys that keep
earlier results valid, settings that travel with the episode, a recording renamed only
when whole, one line for a recording that cannot start, and what the runner built handed
back (`EpisodeRun`), with the lifecycle of what it started owned by it."""

import json
import subprocess
import sys

import pytest

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import EpisodeObserver, Planner
from dynabarn.metrics import Outcome
from dynabarn.planners import get_planner
from dynabarn.planners.registry import PLANNERS, register_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import MACHINE_FIELDS, Topic, read_recording
from dynabarn.recording.schemas import number, obj
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
    assert run_spec(spec).result.to_dict() | clocks == direct.to_dict() | clocks
    fine = run_spec(EpisodeSpec.make(world, "dwa", BARN, seed=2, sim=SimConfig(dt=0.0025, control_rate=20.0))).result
    assert fine.n_ticks != direct.n_ticks  # 20 Hz: about twice the control periods
    assert fine.n_ticks == pytest.approx(2 * fine.sim_time * 10, abs=2)


def test_the_recording_appears_only_whole_and_is_read_back(tmp_path):
    rec = tmp_path / "ep.mcap"
    run = run_spec(EpisodeSpec.make(resolve_world(5), "straight", BARN), record_to=rec)
    result = run.result
    assert run.recording == rec and run.recording_target == rec and run.recording_problem is None
    assert run.world.name == "world_005" and run.world.profile_set  # the world as compiled
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


class _Reporting(Planner):
    """Drives straight on; writes a channel of its own to the recording, reports how many
    periods it drove, and counts its `finish` calls."""

    name = "reporting"

    def __init__(self):
        self.recorder = None
        self.acted = 0
        self.finished: list[str] = []

    def act(self, obs):
        self.acted += 1
        if self.recorder is not None:
            self.recorder.log_json(NOTE.name, obs.time, {"n": self.acted})
        return 1.0, 0.0

    def recording_options(self) -> dict:
        return {"extra_channels": (NOTE,), "extra_metadata": {"source": "test"}}

    def attach_recording(self, recorder) -> None:
        self.recorder = recorder

    def finish(self, outcome: str) -> None:
        self.finished.append(outcome)

    def report(self) -> dict:
        return {"acted": self.acted}


NOTE = Topic(
    "/test/note",
    "dynabarn.TestNote",
    "10 Hz",
    "a planner's own channel",
    json_schema=obj("a planner's note", {"n": number("periods driven")}, ("n",)),
)
BUILT: list[_Reporting] = []


def _reporting() -> _Reporting:
    BUILT.append(_Reporting())
    return BUILT[-1]


@pytest.fixture
def reporting():
    register_planner(_reporting, name="reporting")
    BUILT.clear()
    yield
    PLANNERS.pop("reporting", None)


def test_the_planners_report_and_its_own_channel_come_back_with_the_run(tmp_path, reporting):
    rec = tmp_path / "ep.mcap"
    run = run_spec(EpisodeSpec.make(resolve_world(5), "reporting", BARN), record_to=rec)
    (planner,) = BUILT  # built once, by the runner
    assert run.planner_report == {"acted": planner.acted} and planner.acted == run.result.n_ticks
    assert planner.finished == [run.result.outcome.value]  # finished once, by the loop
    recording = read_recording(rec)
    notes = recording.topic(NOTE.name)
    assert [m["n"] for _, m in notes] == list(range(1, planner.acted + 1))
    assert recording.metadata["source"] == "test"


class _Breaks(EpisodeObserver):
    def on_tick(self, period) -> None:
        raise RuntimeError("an observer's bug")


def test_what_breaks_outside_the_loop_still_finishes_the_planner(reporting):
    with pytest.raises(RuntimeError, match="an observer's bug"):
        run_spec(EpisodeSpec.make(resolve_world(5), "reporting", BARN), observers=[_Breaks()])
    (planner,) = BUILT
    assert planner.finished == ["error"]  # its processes, connections end with the run


class _Live:
    """A live view that counts what the runner does with it."""

    def __init__(self, events: list):
        self.events, self.contexts, self.observers = events, (), ()

    def __enter__(self):
        self.events.append("open")
        return self

    def __exit__(self, *exc) -> None:
        self.events.append("close")

    def watch(self, sim, planner):
        self.events.append(("watch", sim.world.name))
        return ()

    def attach(self, recorder) -> None:
        self.events.append("attach")


def test_the_live_view_opens_after_the_configuration_is_checked_and_always_closes():
    events: list = []
    with pytest.raises(DynabarnError, match="max_speed"):
        run_spec(EpisodeSpec.make(resolve_world(5), "dwa", BARN, config={"max_speed": -1.0}), live=_Live(events))
    assert events == []  # a bad configuration is one line before anything opens
    run_spec(EpisodeSpec.make(resolve_world(5), "stop", BARN), live=_Live(events))
    assert events == ["open", ("watch", "world_005"), "close"]  # nothing recorded: no recorder attached


def test_parts_given_built_run_as_the_spec_names_them():
    """A planner made in code and a simulation compiled once go through the runner like
    any spec: the same result as the registry's planner in a fresh simulation."""
    from dynabarn.sim import Simulation

    world = resolve_world(0)
    spec = EpisodeSpec.make(world, "dwa", get_protocol("barn"), seed=2)
    sim = Simulation(world)
    given = run_spec(spec, planner=get_planner("dwa"), sim=sim).result
    built = run_spec(spec).result
    clocks = {k: 0 for k in MACHINE_FIELDS}  # wall-clock figures differ run to run
    assert given.to_dict() | clocks == built.to_dict() | clocks
    # What is given must be what the spec says: no silent second source of settings.
    with pytest.raises(DynabarnError, match="not the spec's"):
        run_spec(EpisodeSpec.make(resolve_world(1), "dwa", get_protocol("barn")), sim=sim)
    with pytest.raises(DynabarnError, match="takes no configuration"):
        configured = EpisodeSpec.make(world, "dwa", get_protocol("barn"), config={"max_speed": 1.0})
        run_spec(configured, planner=get_planner("dwa"))


def test_only_the_runner_drives_the_loop():
    """Commands, certificates, the checker and the benchmark scripts run episodes through
    `run_spec`; `sim.run_episode` is the runner's loop (and the tests')."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    callers = sorted(
        str(f.relative_to(root))
        for folder in ("dynabarn", "benchmarks", "examples")
        for f in (root / folder).rglob("*.py")
        if re.search(r"(?<!\w)run_episode\(", f.read_text())  # not _run_episode(
    )
    assert callers == ["dynabarn/runner.py", "dynabarn/sim/loop.py"], callers
