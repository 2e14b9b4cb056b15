"""The oracle demonstrator and the behaviour-cloning dataset export."""

import numpy as np
import pytest

from dynabarn import bench, worldset
from dynabarn.cli import demos_main
from dynabarn.demos.dataset import load_dataset
from dynabarn.errors import DynabarnError
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder, read_recording
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world

HARD_AND_MEDIUM = "150,155,200,201,205,210,215"


@pytest.mark.slow
def test_oracle_succeeds_clearly_more_often_than_dwa(tmp_path):
    worlds = worldset.world_set("dynabarn300", worldset.parse_ids(HARD_AND_MEDIUM))
    jobs = bench.make_jobs([("oracle", {}), ("dwa", {})], worlds, get_protocol("barn"), 2)
    rows = bench.run_sweep(jobs, tmp_path, n_workers=2).rows
    wins = {p: sum(r["outcome"] == "success" for r in rows if r["planner"] == p) for p in ("oracle", "dwa")}
    assert wins["oracle"] >= 12 and wins["oracle"] >= wins["dwa"] + 5, wins


def test_oracle_needs_privileged_observations():
    assert get_planner("oracle").privileged


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    d = tmp_path_factory.mktemp("demos")
    # Two oracle successes and one failing straight run.
    for world, planner in ((0, "oracle"), (100, "oracle"), (137, "straight")):
        run_episode(
            resolve_world(world),
            get_planner(planner),
            get_protocol("barn"),
            seed=1,
            observers=[McapRecorder(d / f"w{world}_{planner}.mcap")],
        )
    return d


def test_export_round_trip(demos, tmp_path, capsys):
    out = tmp_path / "ds.npz"
    assert demos_main(["export", str(demos), "--dataset", str(out)]) == 0
    assert "2 episodes" in capsys.readouterr().out
    ds = load_dataset(out)
    n = len(ds["actions"])
    assert ds["scans"].shape == (n, 720) and ds["local_goal"].shape == (n, 2) and ds["scans"].dtype == np.float32
    assert set(ds["episode_source"]) == {"oracle"} and set(ds["episode_outcome"]) == {"success"}
    assert np.all((ds["scans"] >= 0.1) & (ds["scans"] <= 30.0))
    assert np.all(ds["actions"][:, 0] >= -0.5) and np.all(ds["actions"][:, 0] <= 2.0)
    assert np.all(np.abs(ds["actions"][:, 1]) <= 3.14)
    assert np.all(np.hypot(*ds["local_goal"].T) <= 2.0 + 1e-4)
    # Rows equal what the recordings hold.
    for e, name in enumerate(ds["episode_file"]):
        rec = read_recording(demos / name)
        rows = ds["episode"] == e
        scans = np.array([m.ranges for _, m in rec.topic("/scan")], dtype=np.float32)
        cmds = np.array([[m["v"], m["w"]] for _, m in rec.topic("/cmd_vel")], dtype=np.float32)
        np.testing.assert_array_equal(ds["scans"][rows], scans)
        np.testing.assert_array_equal(ds["actions"][rows], cmds)
        np.testing.assert_allclose(ds["time"][rows], [t for t, _ in rec.topic("/scan")])
    # At the start the robot faces the goal along the plan: the local goal is straight ahead.
    first = ds["local_goal"][ds["episode"] == 0][0]
    assert first[0] == pytest.approx(2.0, abs=0.1) and abs(first[1]) < 0.1


def test_export_all_keeps_failures(demos, tmp_path):
    out = tmp_path / "all.npz"
    assert demos_main(["export", str(demos), "--dataset", str(out), "--all"]) == 0
    ds = load_dataset(out)
    assert "collision" in set(ds["episode_outcome"]) and "planner" in set(ds["episode_source"])


def test_export_errors(tmp_path, capsys):
    assert demos_main(["export", str(tmp_path / "none"), "--dataset", str(tmp_path / "x.npz")]) == 2
    assert "no such recording" in capsys.readouterr().err
    bad = tmp_path / "bad.npz"
    np.savez(bad, a=np.zeros(3))
    with pytest.raises(DynabarnError, match="not a dynabarn-demos-v1"):
        load_dataset(bad)


def test_collect_writes_recordings_and_manifest(tmp_path, capsys):
    out = tmp_path / "demos"
    assert demos_main(["collect", "--worlds", "0,1", "--out", str(out), "--jobs", "1"]) == 0
    lines = (out / "manifest.jsonl").read_text().splitlines()
    assert len(lines) == 2 and all('"source": "oracle"' in line for line in lines)
    rec = read_recording(out / "world_000_oracle_barn_s0.mcap")
    assert rec.metadata["synthetic"] is True and rec.metadata["source"] == "oracle"
    # Collecting again adds nothing twice.
    assert demos_main(["collect", "--worlds", "0,1", "--out", str(out), "--jobs", "1"]) == 0
    assert len((out / "manifest.jsonl").read_text().splitlines()) == 2
