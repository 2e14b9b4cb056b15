"""MCAP -> rerun, verified with rerun's own tools."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from dynabarn.cli import replay_main
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder, read_recording
from dynabarn.rerun_replay import save_rrd
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world

RERUN = shutil.which("rerun") or str(Path(__import__("sys").executable).parent / "rerun")


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    paths = []
    for planner, seed in (("dwa", 0), ("straight", 1)):
        p = d / f"{planner}.mcap"
        run_episode(
            resolve_world(0), get_planner(planner), get_protocol("barn"), seed=seed, observers=[McapRecorder(p)]
        )
        paths.append(p)
    return paths


def _rows_per_entity(rrd: Path) -> dict[str, dict[str, int]]:
    """Rows of time-indexed data per entity and component, from `rerun rrd print`."""
    out = subprocess.run([RERUN, "rrd", "print", str(rrd)], capture_output=True, text=True, check=True).stdout
    rows: dict[str, dict[str, int]] = {}
    for m in re.finditer(r"with (\d+) rows .*? - (\S+) - data columns: \[([^\]]*)\]", out):
        n, entity, columns = int(m.group(1)), m.group(2), m.group(3).split()
        for c in columns:
            rows.setdefault(entity, {}).setdefault(c, 0)
            rows[entity][c] += n
    return rows


def test_rrd_verifies_and_holds_every_message(recordings, tmp_path):
    rec = read_recording(recordings[0])
    rrd = tmp_path / "a.rrd"
    (counts,) = save_rrd([rec], rrd)
    verify = subprocess.run([RERUN, "rrd", "verify", str(rrd)], capture_output=True, text=True)
    assert verify.returncode == 0, verify.stderr
    stats = subprocess.run([RERUN, "rrd", "stats", str(rrd)], capture_output=True, text=True)
    assert stats.returncode == 0 and "num_chunks" in stats.stdout
    rows = _rows_per_entity(rrd)
    run = "/runs/dwa_s0"
    assert rows[f"{run}/scan"]["Points3D:positions"] == len(rec.topic("/scan")) == counts.scans
    assert rows[f"{run}/robot"]["Transform3D:translation"] == len(rec.topic("/robot/pose")) == counts.poses
    assert rows[f"{run}/obstacles"]["Cylinders3D:centers"] == len(rec.topic("/world/obstacles"))
    assert rows[f"/metrics/v{run}"]["Scalars:scalars"] == len(rec.topic("/cmd_vel"))
    assert rows[f"{run}/local_plan"]["LineStrips3D:strips"] == len(rec.topic("/planner/debug"))
    assert "/world/walls" in rows and "/description" in rows


def test_two_recordings_side_by_side(recordings, tmp_path, capsys):
    rrd = tmp_path / "two.rrd"
    assert replay_main([str(p) for p in recordings] + ["--save", str(rrd)]) == 0
    assert "2 recording(s)" in capsys.readouterr().out
    rows = _rows_per_entity(rrd)
    assert "/runs/dwa_s0/scan" in rows and "/runs/straight_s1/scan" in rows


def test_truncated_recording_replays_to_its_cut(recordings, tmp_path, capsys):
    data = recordings[0].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    rrd = tmp_path / "cut.rrd"
    assert replay_main([str(cut), "--save", str(rrd)]) == 0
    assert "truncated" in capsys.readouterr().err
    rows = _rows_per_entity(rrd)
    assert 0 < rows["/runs/dwa_s0/scan"]["Points3D:positions"] == len(read_recording(cut).topic("/scan"))


def test_without_display_saves_instead(recordings, tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    src = tmp_path / "r.mcap"
    shutil.copy(recordings[1], src)
    assert replay_main([str(src)]) == 0
    assert "no display" in capsys.readouterr().err and src.with_suffix(".rrd").is_file()


def test_bad_recording(tmp_path, capsys):
    bad = tmp_path / "bad.mcap"
    bad.write_text("not an mcap")
    assert replay_main([str(bad), "--save", str(tmp_path / "x.rrd")]) == 2
    assert "not an MCAP file" in capsys.readouterr().err


def test_shaped_and_static_obstacles_replay_as_their_archetypes(tmp_path):
    from dynabarn.mjcf import write_world
    from dynabarn.worlds.generate import generate_world
    from dynabarn.worlds.profiles import SHAPE_MIXES, STATIC_FIELDS, get_profile_set

    world = generate_world(
        250, get_profile_set("table1"), shapes=SHAPE_MIXES["mixed"], static_field=STATIC_FIELDS["barn-grid"]
    )
    path = tmp_path / "w.xml"
    write_world(world, path)
    mcap = tmp_path / "w.mcap"
    run_episode(path, get_planner("stop"), get_protocol("barn"), seed=0, observers=[McapRecorder(mcap)])
    rec = read_recording(mcap)
    rrd = tmp_path / "w.rrd"
    save_rrd([rec], rrd)
    rows = _rows_per_entity(rrd)
    n = len(rec.topic("/world/obstacles"))
    counts = {s: sum(o.shape == s for o in world.obstacles) for s in ("cylinder", "box", "capsule")}
    assert all(counts.values()), counts
    # One row per obstacle update, each holding that kind's obstacles.
    assert rows["/runs/stop_s0/obstacles"]["Cylinders3D:centers"] == n
    assert rows["/runs/stop_s0/obstacle_boxes"]["Boxes3D:quaternions"] == n
    assert rows["/runs/stop_s0/obstacle_capsules"]["Capsules3D:quaternions"] == n
    assert "Cylinders3D:centers" in rows["/world/static_obstacles"]


def test_tracks_replay_beside_the_true_obstacles(tmp_path):
    """A planner that tracks: one row of track circles and velocity arrows per control tick,
    each row holding that tick's tracks."""
    mcap = tmp_path / "p.mcap"
    run_episode(
        resolve_world(0), get_planner("predictive"), get_protocol("barn"), seed=0, observers=[McapRecorder(mcap)]
    )
    rec = read_recording(mcap)
    rrd = tmp_path / "p.rrd"
    save_rrd([rec], rrd)
    rows = _rows_per_entity(rrd)
    ticks = rec.topic("/perception/tracks")
    assert len(ticks) > 50 and any(len(m["ids"]) for _, m in ticks)
    assert rows["/runs/predictive_s0/tracks"]["LineStrips3D:strips"] == len(ticks)
    assert rows["/runs/predictive_s0/track_velocities"]["Arrows3D:vectors"] == len(ticks)
    assert rows["/runs/predictive_s0/obstacles"]["Cylinders3D:centers"] == len(rec.topic("/world/obstacles"))
