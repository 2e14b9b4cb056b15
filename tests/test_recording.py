"""MCAP recordings: real files, read back with the plain mcap library and ours."""

import os
import signal
import subprocess
import sys

import pytest
from mcap.reader import make_reader

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import Planner
from dynabarn.metrics import Outcome
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder, RecordingError, read_recording
from dynabarn.recording.background import BackgroundRecorder
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world
from tests.helpers import slow_recorded_episode

BARN = get_protocol("barn")


def _record(path, world=137, planner="straight", seed=2):
    return run_episode(resolve_world(world), get_planner(planner), BARN, seed=seed, observers=[McapRecorder(path)])


def test_recording_reads_back_with_plain_mcap(tmp_path):
    path = tmp_path / "a.mcap"
    result = _record(path, world=0, seed=1)
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = {c.topic for c in summary.channels.values()}
        schemas = {s.name for s in summary.schemas.values()}
        n_messages = summary.statistics.message_count
        max_chunk = max(ci.uncompressed_size for ci in summary.chunk_indexes)
    assert {
        "/scan",
        "/robot/pose",
        "/world/obstacles",
        "/world/static",
        "/goal",
        "/cmd_vel",
        "/metrics",
        "/world/metadata",
        "/episode/result",
    } <= topics
    assert {"foxglove.LaserScan", "foxglove.PoseInFrame", "foxglove.SceneUpdate"} <= schemas
    assert max_chunk <= 2 * 64 * 1024, "small chunks, so a killed writer loses little"

    rec = read_recording(path)
    assert not rec.truncated
    assert sum(rec.counts().values()) == n_messages
    assert rec.counts()["/scan"] == result.n_ticks
    assert len(rec.topic("/scan")[0][1].ranges) == 720
    # Poses at 50 Hz from t = 0 to the end, on simulated time.
    poses = rec.topic("/robot/pose")
    assert poses[0][0] == 0.0 and poses[-1][0] == pytest.approx(result.sim_time)
    n_steps = round(result.sim_time / 0.005)
    # every fourth physics step from t = 0, plus the final pose when it falls between
    assert len(poses) == n_steps // 4 + 1 + (n_steps % 4 > 0)
    assert rec.result["outcome"] == result.outcome.value
    assert rec.metadata["seed"] == 1 and rec.metadata["world"]["name"] == "world_000"
    assert len(rec.topic("/world/obstacles")[0][1].entities[0].cylinders) == result_obstacles(rec)


def test_topic_table_is_what_is_recorded_and_what_the_readme_says(tmp_path):
    from pathlib import Path

    from dynabarn.recording.topics import TOPICS, markdown_table

    path = tmp_path / "predictive.mcap"
    _record(path, world=0, planner="predictive", seed=1)  # a local plan and tracks: every topic appears
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    recorded = {c.topic: (summary.schemas[c.schema_id].name, c.message_encoding) for c in summary.channels.values()}
    assert recorded == {t.name: (t.schema, t.encoding) for t in TOPICS}
    page = (Path(__file__).resolve().parent.parent / "docs" / "concepts" / "recordings.md").read_text()
    assert markdown_table() in page, "docs/concepts/recordings.md's topic table: regenerate it from markdown_table()"


def result_obstacles(rec):
    return len(rec.metadata["world"]["obstacles"])


def test_same_seed_gives_byte_identical_recordings(tmp_path):
    _record(tmp_path / "a.mcap", seed=7)
    _record(tmp_path / "b.mcap", seed=7)
    _record(tmp_path / "c.mcap", seed=8)
    a, b, c = ((tmp_path / n).read_bytes() for n in ("a.mcap", "b.mcap", "c.mcap"))
    assert a == b
    assert a != c


def test_truncated_file_is_recovered_up_to_the_cut(tmp_path):
    path = tmp_path / "full.mcap"
    _record(path, world=0, planner="stop", seed=0)  # 100 s of run, ~1000 scans
    full = read_recording(path)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    rec = read_recording(cut)
    assert rec.truncated
    n_full, n_cut = full.counts()["/scan"], rec.counts()["/scan"]
    assert 0.4 * n_full < n_cut < 0.7 * n_full
    # What was recovered is exactly the beginning of the full recording.
    assert [t for t, _ in rec.topic("/scan")] == [t for t, _ in full.topic("/scan")][:n_cut]


def test_not_an_mcap_file(tmp_path):
    p = tmp_path / "x.mcap"
    p.write_bytes(b"hello world, not mcap")
    with pytest.raises(RecordingError, match="not an MCAP file"):
        read_recording(p)
    with pytest.raises(DynabarnError, match="not found"):
        read_recording(tmp_path / "missing.mcap")


class Interrupts(Planner):
    name = "interrupts"

    def act(self, obs):
        if obs.time >= 1.0:
            raise KeyboardInterrupt
        return 1.0, 0.0


@pytest.mark.parametrize("recorder", [McapRecorder, BackgroundRecorder])
def test_ctrl_c_leaves_a_complete_recording(tmp_path, recorder):
    path = tmp_path / "i.mcap"
    with pytest.raises(KeyboardInterrupt):
        run_episode(resolve_world(0), Interrupts(), BARN, observers=[recorder(path)])
    rec = read_recording(path)
    assert not rec.truncated
    assert rec.result["outcome"] == "error" and rec.result["reason"] == "interrupted"
    assert rec.counts()["/scan"] == 10  # ticks at t = 0.0 ... 0.9; the one at 1.0 was interrupted


def test_planner_error_keeps_recording_intact(tmp_path):
    class Raises(Planner):
        name = "raises"

        def act(self, obs):
            if obs.time > 0.5:
                raise ValueError("bad")
            return 0.5, 0.0

    path = tmp_path / "e.mcap"
    r = run_episode(resolve_world(0), Raises(), BARN, observers=[McapRecorder(path)])
    assert r.outcome is Outcome.ERROR
    rec = read_recording(path)
    assert not rec.truncated and "ValueError: bad" in rec.result["reason"]


def test_killed_process_keeps_what_it_wrote(tmp_path):
    """SIGKILL a real recording process midway: what it wrote reads back up to the kill from
    the staging file beside the target, and the finished recording already at the target
    (an earlier run's) is untouched: nothing finished is overwritten by a cut file."""
    path = tmp_path / "killed.mcap"
    path.write_bytes(b"an earlier, finished recording")
    script = slow_recorded_episode(path, "McapRecorder(path)", say='"halfway"')
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "running"
    assert proc.stdout.readline().strip() == "halfway"  # 400 ticks of 1000 written: kill it now
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert path.read_bytes() == b"an earlier, finished recording"
    rec = read_recording(tmp_path / "killed.mcap.part")
    assert rec.truncated
    assert rec.counts()["/scan"] > 100
    assert rec.result is None


def test_beyond_paper_worlds_record_byte_identically(tmp_path):
    """Shapes, a static field and avoiding obstacles: still the same bytes for the same seed."""
    from dynabarn.mjcf import write_world
    from dynabarn.worlds.generate import generate_world
    from dynabarn.worlds.profiles import SHAPE_MIXES, STATIC_FIELDS, get_profile_set

    world = generate_world(
        250,
        get_profile_set("table1"),
        shapes=SHAPE_MIXES["mixed"],
        static_field=STATIC_FIELDS["barn-grid"],
        behavior="avoid",
    )
    path = tmp_path / "world_250.xml"
    write_world(world, path)
    files = []
    for name, seed in (("a", 3), ("b", 3), ("c", 4)):
        files.append(tmp_path / f"{name}.mcap")
        run_episode(path, get_planner("dwa"), get_protocol("barn"), seed=seed, observers=[McapRecorder(files[-1])])
    a, b, c = (f.read_bytes() for f in files)
    assert a == b and a != c


def test_every_topic_protobuf_ones_too_is_defined_once_in_the_table():
    from dynabarn.recording.layout import SCENE_TOPICS
    from dynabarn.recording.topics import TOPICS
    from dynabarn.recording.writer import LATCHED

    for t in TOPICS:
        assert (t.message_type is None) == (t.json_schema is not None), t.name  # one kind each
        if t.message_type is not None:
            assert t.message_type.get_schema().name == t.schema, t.name
    assert set(LATCHED) == {t.name for t in TOPICS if t.rate == "once"}
    assert {t.schema for t in SCENE_TOPICS} <= {"foxglove.SceneUpdate", "foxglove.LaserScan", "foxglove.PoseInFrame"}
