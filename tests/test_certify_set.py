"""`dynabarn-worlds certify SET`: certificates into a set's index.json, kept when the set is
regenerated to the same bytes, and read by the sweep's summaries."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dynabarn.cli.bench import bench_main
from dynabarn.cli.worlds import worlds_main
from dynabarn.provenance import REPO_ROOT

EXAMPLE = REPO_ROOT / "examples" / "profiles" / "sprint.toml"


@pytest.fixture(scope="module")
def certified(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("certified") / "w"
    assert worlds_main(["generate", "--out", str(out), "--profile-file", str(EXAMPLE)]) == 0
    argv = ["certify", str(out), "--worlds", "0,250", "--trials", "2", "--jobs", "1"]
    assert worlds_main(argv) == 0
    return out


def test_certificates_are_recorded_per_world_and_trial(certified, capsys):
    index = json.loads((certified / "index.json").read_text())
    entries = {e["id"]: e for e in index["worlds"]}
    assert "certificates" not in entries[1]  # only the worlds asked for
    for world_id in (0, 250):
        record = entries[world_id]["certificates"]["barn"]
        assert record["sha256"] == entries[world_id]["sha256"]
        assert [t["seed"] for t in record["trials"]] == [0, 1]
        for trial in record["trials"]:
            by_search = "arrival" in trial and trial["replay"]["outcome"] == "success"
            by_oracle = trial.get("oracle", {}).get("outcome") == "success"
            assert trial["certified"] == (by_search or by_oracle)
            assert 0.0 <= trial["clock_offset"] < 5.0
        assert record["certified_trials"] == sum(t["certified"] for t in record["trials"])
    facts = index["certification"]["barn"]
    assert facts["resolution"]["cell"] > 0 and 9.5 <= facts["unobstructed_arrival"] <= 9.6
    # Asked again, nothing is computed again (the same file, byte for byte).
    before = (certified / "index.json").read_bytes()
    assert worlds_main(["certify", str(certified), "--worlds", "0,250", "--trials", "2", "--jobs", "1"]) == 0
    assert (certified / "index.json").read_bytes() == before
    assert "certified" in capsys.readouterr().out


def test_verify_recomputes_and_finds_a_changed_certificate(certified, tmp_path, capsys):
    import shutil

    folder = tmp_path / "copy"
    shutil.copytree(certified, folder)
    argv = ["certify", str(folder), "--worlds", "0", "--verify", "--jobs", "1"]
    assert worlds_main(argv) == 0
    assert "2 trials checked" in capsys.readouterr().out
    index = json.loads((folder / "index.json").read_text())
    entry = next(e for e in index["worlds"] if e["id"] == 0)
    entry["certificates"]["barn"]["trials"][1]["arrival"] = 1.0  # a number someone changed
    (folder / "index.json").write_text(json.dumps(index))
    assert worlds_main(argv) == 1
    assert "seed 1: arrival 1.0 ->" in capsys.readouterr().out


def test_show_prints_a_worlds_certificate(certified, capsys):
    assert worlds_main(["show", str(certified / "world_250.xml")]) == 0
    assert "certified solvable (barn):" in capsys.readouterr().out


def test_regenerating_the_same_worlds_keeps_their_certificates(certified):
    before = (certified / "index.json").read_bytes()
    assert worlds_main(["generate", "--out", str(certified), "--profile-file", str(EXAMPLE)]) == 0
    assert (certified / "index.json").read_bytes() == before


def test_the_sweep_reports_success_over_certified_worlds(certified, tmp_path, capsys):
    out = tmp_path / "results"
    argv = ["--planner", "straight", "--no-floor", "--set", str(certified), "--worlds", "0,250", "--trials", "2"]
    assert bench_main([*argv, "--jobs", "1", "--out", str(out)]) == 0
    worlds = {w["id"]: w for w in json.loads((out / "worlds.json").read_text())["worlds"]}
    assert set(worlds[0]["certificates"]["barn"]["seeds"]) == {0, 1}
    printed = capsys.readouterr().out
    assert "on certified" in printed
    assert "certified solvable" in (out / "summary.md").read_text()


def test_an_unknown_set_is_one_line_and_exit_2(tmp_path, capsys):
    assert worlds_main(["certify", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "unknown world set" in err


def test_a_world_not_in_the_set_is_one_line_and_exit_2(certified, capsys):
    assert worlds_main(["certify", str(certified), "--worlds", "0,999"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "999" in err


def test_a_full_disk_is_one_line_and_exit_2(certified, tmp_path, monkeypatch, capsys):
    import shutil

    folder = tmp_path / "full"
    shutil.copytree(certified, folder)
    before = (folder / "index.json").read_bytes()

    def no_space(path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("dynabarn.bench.certify.write_atomically", no_space)
    assert worlds_main(["certify", str(folder), "--worlds", "1", "--trials", "1", "--jobs", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "No space left on device" in err
    assert (folder / "index.json").read_bytes() == before


def test_where_the_search_finds_no_witness_the_oracles_episode_is_tried(tmp_path):
    """A spawn with an obstacle parked on it: the search says why it has no witness, the
    exact oracle's episode of the trial is run and fails too, so it stays uncertified."""
    from helpers import obstacle

    from dynabarn.worlds.spec import WorldSpec
    from dynabarn.worldset import write_worlds

    parked = WorldSpec(
        name="world_000",
        world_id=0,
        difficulty="easy",
        obstacles=(obstacle("parked", [[0, 11.0, 0.0], [50, 11.0, 0.0]]),),
    )
    folder = tmp_path / "parked"
    write_worlds([parked], folder, meta={"generator": "test"}, sets={"all": [0]})
    assert worlds_main(["certify", str(folder), "--trials", "1", "--jobs", "1"]) == 0
    (trial,) = json.loads((folder / "index.json").read_text())["worlds"][0]["certificates"]["barn"]["trials"]
    assert not trial["certified"] and "spawn" in trial["reason"]
    assert trial["oracle"]["outcome"] == "collision" and "by" not in trial


def test_footprint_certificates_are_version_3_and_verified_at_their_own_resolution(tmp_path, capsys):
    out = tmp_path / "w"
    assert worlds_main(["generate", "--out", str(out), "--profile-file", str(EXAMPLE)]) == 0
    argv = ["certify", str(out), "--worlds", "0", "--trials", "1", "--jobs", "1", "--footprint"]
    assert worlds_main(argv) == 0
    index = json.loads((out / "index.json").read_text())
    assert index["certification"]["barn"]["resolution"]["version"] == 3
    assert index["certification"]["barn"]["resolution"]["footprint"] is True
    record = next(e for e in index["worlds"] if e["id"] == 0)["certificates"]["barn"]
    assert record["resolution_version"] == 3
    # Verified under the footprint it was made with: no difference.
    assert worlds_main(["certify", str(out), "--worlds", "0", "--verify", "--jobs", "1"]) == 0
    assert "no difference" in capsys.readouterr().out
    # A tier's draws stay at the disc's resolution.
    assert worlds_main(["certify", "tier-mixed", "--redraw", "--footprint"]) == 2
    assert "not with --footprint" in capsys.readouterr().err


def test_goal_guided_certificates_are_version_4_and_verified_at_their_own_resolution(tmp_path, capsys):
    out = tmp_path / "w"
    assert worlds_main(["generate", "--out", str(out), "--profile-file", str(EXAMPLE)]) == 0
    argv = ["certify", str(out), "--worlds", "0", "--trials", "1", "--jobs", "1", "--footprint", "--beam", "300"]
    assert worlds_main(argv) == 0
    index = json.loads((out / "index.json").read_text())
    resolution = index["certification"]["barn"]["resolution"]
    assert resolution["version"] == 4 and resolution["beam"] == 300 and resolution["footprint"] is True
    assert next(e for e in index["worlds"] if e["id"] == 0)["certificates"]["barn"]["resolution_version"] == 4
    assert worlds_main(["certify", str(out), "--worlds", "0", "--verify", "--jobs", "1"]) == 0
    assert "no difference" in capsys.readouterr().out
    # A resolution the search does not have is one line, exit 2, not a traceback.
    index["certification"]["barn"]["resolution"] = {**resolution, "version": 3}
    (out / "index.json").write_text(json.dumps(index))
    assert worlds_main(["certify", str(out), "--worlds", "0", "--verify", "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert "resolution is not one the search has" in err and "Traceback" not in err


def test_recertify_takes_a_whole_tier_and_nothing_else(capsys):
    for argv in (
        ["certify", "paper60", "--recertify"],
        ["certify", "tier-mixed", "--recertify", "--worlds", "0-3"],
        ["certify", "tier-mixed", "--recertify", "--redraw"],
    ):
        assert worlds_main(argv) == 2
        assert "--recertify certifies a whole tier's committed draws" in capsys.readouterr().err
