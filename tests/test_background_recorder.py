"""The writer-process recorder (issue 32, item 4): the same file as the recorder in the
episode's process, byte for byte; a writer that dies or an episode process that is killed
loses nothing finished and leaves no process behind (Ctrl-C: test_recording, for both)."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from dynabarn.errors import EndEpisode
from dynabarn.interfaces import Planner
from dynabarn.metrics import Outcome
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder, read_recording
from dynabarn.recording.background import BackgroundRecorder
from dynabarn.runner import EpisodeSpec, RecordingFailed, run_spec
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world
from tests.helpers import slow_recorded_episode

BARN = get_protocol("barn")


def _both(tmp_path, world: int, make_planner, seconds: float | None = None):
    """The same episode recorded both ways: (in-process bytes, writer-process bytes, result)."""
    files = []
    for name, recorder in (("a", McapRecorder), ("b", BackgroundRecorder)):
        path = tmp_path / f"{name}.mcap"
        result = run_episode(resolve_world(world), make_planner(), BARN, seed=3, observers=[recorder(path)])
        files.append(path.read_bytes())
    return files[0], files[1], result


@pytest.mark.parametrize("planner", ["dwa", "predictive", "straight"])
def test_writer_process_writes_the_same_bytes(tmp_path, planner):
    # dwa sends its plans each tick (debug), predictive its tracks; straight neither.
    a, b, result = _both(tmp_path, 210, lambda: get_planner(planner))
    assert result.outcome is not None
    assert a == b
    rec = read_recording(tmp_path / "b.mcap")
    assert not rec.truncated and rec.counts()["/scan"] >= 10 * int(result.sim_time)


class _EndsEarly(Planner):
    name = "ends_early"

    def __init__(self, how: str, at: float = 2.0) -> None:
        self.how, self.at = how, at

    def act(self, obs):
        if obs.time >= self.at - 1e-9:
            if self.how == "error":
                raise ValueError("bad")
            raise EndEpisode("stopped by the operator")
        return 0.8, 0.1


@pytest.mark.parametrize("how", ["error", "end"])
def test_an_episode_ended_early_is_recorded_the_same_way(tmp_path, how):
    a, b, result = _both(tmp_path, 5, lambda: _EndsEarly(how))
    assert result.outcome is Outcome.ERROR and a == b


@pytest.mark.parametrize("ticks", [0, 1, 4, 5, 12, 28, 29, 60])
def test_every_episode_length_is_recorded_the_same_way(tmp_path, ticks):
    """Ended after as many ticks as the first batches hold (4, 8, 16, 32, then 64), or one more."""
    a, b, result = _both(tmp_path, 5, lambda: _EndsEarly("end", at=ticks * 0.1))
    assert a == b and round(result.sim_time / 0.1) == ticks


def test_a_writer_that_dies_stops_the_recording_not_the_episode(tmp_path):
    recorder = BackgroundRecorder(tmp_path / "w.mcap")

    class KillsTheWriter(Planner):
        name = "kills_the_writer"

        def act(self, obs):
            if abs(obs.time - 10.0) < 1e-9:
                # Once the writer has put some chunks on disk (it runs behind the episode).
                deadline = time.monotonic() + 30
                while recorder.staging.stat().st_size < 200_000 and time.monotonic() < deadline:
                    time.sleep(0.01)
                recorder._writer.process.kill()
                recorder._writer.process.wait()
            return 0.5, 0.0

    result = run_episode(resolve_world(0), KillsTheWriter(), BARN, seed=1, observers=[recorder])
    assert result.outcome is not None and result.sim_time > 10.0
    assert recorder.stopped and "writer process ended" in recorder.stopped
    assert not (tmp_path / "w.mcap").exists()  # never renamed: what it wrote stays NAME.part
    assert read_recording(tmp_path / "w.mcap.part").truncated


def test_a_recording_that_cannot_start_is_one_error(tmp_path):
    (tmp_path / "taken.mcap").mkdir()
    spec = EpisodeSpec.make(resolve_world(0), "stop", BARN)
    with pytest.raises(RecordingFailed, match="is a folder"):
        run_spec(spec, record_to=tmp_path / "taken.mcap")


def test_a_killed_episode_process_leaves_its_start_and_no_writer(tmp_path):
    """SIGKILL the episode's process: its writer sees the pipe close, closes what it was
    sent into NAME.part (never renamed: there is no result) and exits; an earlier finished
    recording at the target is untouched."""
    path = tmp_path / "killed.mcap"
    path.write_bytes(b"an earlier, finished recording")
    script = slow_recorded_episode(path, "BackgroundRecorder(path)", say="recorder._writer.process.pid")
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "running"
    writer_pid = int(proc.stdout.readline())
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    deadline = time.monotonic() + 30
    while _alive(writer_pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(writer_pid)
    assert path.read_bytes() == b"an earlier, finished recording"
    rec = read_recording(tmp_path / "killed.mcap.part")
    assert rec.counts()["/scan"] > 100 and rec.result is None


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"  # a zombie has exited
    except FileNotFoundError:
        return False


def test_without_a_writer_process_the_episode_records_in_its_own(tmp_path, monkeypatch):
    import dynabarn.recording.background as background

    def cannot_start():
        raise OSError(2, "no interpreter to start")

    monkeypatch.setattr(background, "_take_writer", cannot_start)
    a, b, result = _both(tmp_path, 5, lambda: get_planner("dwa"))
    assert a == b and result.outcome is not None


def test_a_batch_of_following_periods_takes_its_poses_at_once(tmp_path):
    """The poses of periods that follow each other, taken in one go, are each period's own
    (`Episode.pose_steps` per period), the off-grid end of an ended episode included."""
    from dynabarn.sim import Simulation
    from dynabarn.sim.episode import Episode

    episode = Episode(Simulation(resolve_world(5)), BARN, seed=0)
    every = episode.sim.config.pose_every
    recorder = BackgroundRecorder(tmp_path / "x.mcap")
    recorder._episode = episode
    for spans in (
        [(0, 20, False), (20, 40, False), (40, 53, True)],  # the first period, and an end off the grid
        [(60, 80, False), (80, 100, False)],
        [(100, 120, False), (120, 120 + every, True)],
    ):
        recorder._spans, recorder._count = dict(enumerate(spans)), len(spans)
        idx, counts = recorder._pose_steps()
        each = [episode.pose_steps(*span) for span in spans]
        assert counts == [len(s) for s in each] and idx.tolist() == np.concatenate(each).tolist()
    # Periods that do not follow each other (or a row without its poses): each its own.
    recorder._spans, recorder._count = {0: (0, 20, False), 2: (40, 60, False)}, 3
    idx, counts = recorder._pose_steps()
    assert (
        counts[1] == 0
        and idx.tolist()
        == np.concatenate([episode.pose_steps(0, 20, False), episode.pose_steps(40, 60, False)]).tolist()
    )
