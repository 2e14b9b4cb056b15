"""Verification that tells "cannot run here" from "differs" (issue 56), a pass on nothing
refused, and metadata.json that keeps every invocation that wrote its folder."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from dynabarn.cli.bench import bench_main

ONE = ["--set", "paper60", "--worlds", "200", "--trials", "1", "--jobs", "1"]


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """Two invocations into one folder: `stop` (with the floor), then `dwa`."""
    out = tmp_path_factory.mktemp("verify_outcomes") / "sweep"
    assert bench_main(["--planner", "stop", *ONE, "--out", str(out)]) == 0
    assert bench_main(["--planner", "dwa", "--no-floor", *ONE, "--out", str(out)]) == 0
    return out


def test_metadata_keeps_every_invocation(folder):
    meta = json.loads((folder / "metadata.json").read_text())
    assert meta["planners"] == ["dwa", "stop", "straight"]
    first, second = meta["invocations"]
    assert first["planners"] == ["stop", "straight"] and second["planners"] == ["dwa"]
    assert first["command"][:3] == ["dynabarn-bench", "--planner", "stop"]
    assert "--no-floor" in second["command"] and first["episodes"] == 2 and second["episodes"] == 1
    for invocation in (first, second):
        assert invocation["versions"]["mujoco"] and invocation["machine"]["cores"] >= 1
        assert invocation["when"].endswith("Z")


def test_metadata_from_before_invocations_counts_as_one(folder, tmp_path):
    """A folder written before invocations were kept: its one record becomes the first."""
    copy = tmp_path / "old"
    shutil.copytree(folder, copy)
    meta = json.loads((copy / "metadata.json").read_text())
    del meta["invocations"]
    meta["planners"] = ["dwa"]
    (copy / "metadata.json").write_text(json.dumps(meta))
    assert bench_main(["--planner", "stop", "--no-floor", *ONE, "--out", str(copy)]) == 0
    meta = json.loads((copy / "metadata.json").read_text())
    assert [i["planners"] for i in meta["invocations"]] == [["dwa"], ["stop"]]
    assert "recovered" in meta["invocations"][0] and meta["planners"] == ["dwa", "stop"]


def test_a_row_needing_a_missing_extra_is_not_checked(folder, tmp_path, monkeypatch, capsys):
    """The issue's false "does not reproduce": a td3 row where PyTorch is not installed is
    not checked, with the install command; exit 3, not 1."""
    copy = tmp_path / "td3"
    shutil.copytree(folder, copy)
    rows = [json.loads(line) for line in (copy / "results.jsonl").read_text().splitlines()]
    stop = next(r for r in rows if r["planner"] == "stop")
    stop["key"] = stop["key"].replace("stop|", "td3|", 1)
    stop["planner"] = "td3"
    (copy / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    monkeypatch.setitem(sys.modules, "torch", None)  # `import torch` raises ImportError
    code = bench_main(["--verify", str(copy), "--sample", "all", "--jobs", "1"])
    out = capsys.readouterr().out
    assert code == 3, out
    assert "not checked" in out and "pip install 'dynabarn[learn]'" in out and "DIFFERS" not in out
    verdict = json.loads((copy / "verification.json").read_text())
    assert verdict["ok"] and verdict["not_checked"] == 1 and verdict["checked"] == 2 and not verdict["complete"]


def test_every_row_reproducing_exits_zero_and_a_difference_one(folder, tmp_path, capsys):
    assert bench_main(["--verify", str(folder), "--sample", "all"]) == 0
    assert "3 rows re-run: 3 identical" in capsys.readouterr().out
    copy = tmp_path / "differs"
    shutil.copytree(folder, copy)
    rows = [json.loads(line) for line in (copy / "results.jsonl").read_text().splitlines()]
    rows[0]["time"] = rows[0]["time"] + 1.0
    (copy / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert bench_main(["--verify", str(copy), "--sample", "all"]) == 1


def test_the_site_shows_only_a_complete_verdict(folder):
    from dynabarn.bench.report import _verification

    bench_main(["--verify", str(folder), "--sample", "1"])
    verdict = json.loads((folder / "verification.json").read_text())
    for complete in (True, False):
        (folder / "verification.json").write_text(json.dumps(verdict | {"complete": complete}))
        assert (_verification(folder, site=True) is not None) is complete
        assert _verification(folder) is not None
    (folder / "verification.json").write_text(json.dumps(verdict))


def test_certify_verify_on_worlds_without_certificates_refuses(tmp_path):
    from dynabarn.provenance import SHIPPED_WORLDS
    from tests.test_fuzz import one_clear_line

    out = tmp_path / "set"
    shutil.copytree(SHIPPED_WORLDS, out)
    index = json.loads((out / "index.json").read_text())
    for entry in index["worlds"]:
        entry.pop("certificates", None)
    (out / "index.json").write_text(json.dumps(index))
    line = one_clear_line("worlds", ["certify", str(out), "--verify", "--worlds", "5"])
    assert "none of the 1 world(s) asked for has a barn certificate to verify" in line


def test_a_row_from_before_a_tracking_measure_was_added_reproduces_with_a_note(tmp_path, capsys):
    """A row written before the scorer counted CLEAR-MOT switches (`id_switches_mot`): the
    re-run agrees on every measure the row has and adds one, a note; a measure it has that
    differs is still a difference."""
    out = tmp_path / "tracked"
    assert bench_main(["--planner", "predictive", "--no-floor", *ONE, "--out", str(out)]) == 0
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert "id_switches_mot" in rows[0]["tracking"]
    del rows[0]["tracking"]["id_switches_mot"]
    (out / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    code = bench_main(["--verify", str(out), "--sample", "all", "--jobs", "1"])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "now reports tracking measures the row's version did not: id_switches_mot" in printed
    rows[0]["tracking"]["id_switches"] += 1
    (out / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    code = bench_main(["--verify", str(out), "--sample", "all", "--jobs", "1"])
    printed = capsys.readouterr().out
    assert code == 1 and "DIFFERS" in printed and "tracking" in printed, printed


def _verify_with(out: Path, rows: list[dict], capsys) -> tuple[int, str]:
    (out / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    code = bench_main(["--verify", str(out), "--sample", "all", "--jobs", "1"])
    return code, capsys.readouterr().out


@pytest.mark.parametrize("world_set", ["tier-mixed", "paper60"])
def test_a_recall_scored_before_the_static_field_fix_is_excused_only_there_and_only_alone(world_set, tmp_path, capsys):
    """Rows written before issue 57's scoring fix counted obstacles hidden behind standing
    cylinders as in view: on a world with a static field, a row without the later scorer's
    `id_switches_mot` whose recall alone differs reproduces, with a note; without a static
    field, from the later scorer, or with another measure off, it differs."""
    out = tmp_path / world_set
    args = ["--planner", "predictive", "--no-floor", "--set", world_set, "--worlds", "200", "--trials", "1"]
    assert bench_main([*args, "--jobs", "1", "--out", str(out)]) == 0
    (row,) = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    old = {k: v for k, v in row["tracking"].items() if k != "id_switches_mot"} | {
        "recall": row["tracking"]["recall"] / 2
    }
    code, printed = _verify_with(out, [row | {"tracking": old}], capsys)
    if world_set == "tier-mixed":
        assert code == 0 and "scored before issue 57's fix" in printed, printed
    else:
        assert code == 1 and "DIFFERS" in printed, printed
    later = row["tracking"] | {"recall": old["recall"]}  # the later scorer: no excuse
    code, printed = _verify_with(out, [row | {"tracking": later}], capsys)
    assert code == 1 and "DIFFERS" in printed, printed
    also_off = old | {"precision": old["precision"] / 2}
    code, printed = _verify_with(out, [row | {"tracking": also_off}], capsys)
    assert code == 1 and "DIFFERS" in printed, printed


def test_a_world_of_the_same_name_with_other_bytes_does_not_hide_the_right_one_further_on(tmp_path):
    """Worlds are found by name under each place in turn: a set whose world_201.xml is
    another world (the paper's 300 beside a mixed set) is passed over for the place that
    holds the row's bytes; where no place does, the other bytes are what is said."""
    from dynabarn.bench.row_rules import row_world_file
    from dynabarn.world_file import world_sha256

    first, second = tmp_path / "first", tmp_path / "second"
    for folder, text in ((first, "<mujoco model='a'/>"), (second, "<mujoco model='b'/>")):
        folder.mkdir()
        (folder / "world_201.xml").write_text(text)
    row = {"world_file": "elsewhere/world_201.xml", "world_sha256": world_sha256(second / "world_201.xml")}
    assert row_world_file(row, [first, second], "world_201.xml") == (second / "world_201.xml", "")
    path, problem = row_world_file(row | {"world_sha256": "0" * 64}, [first, second], "world_201.xml")
    assert path is None and "first/world_201.xml has other bytes than the row's" in problem
    path, problem = row_world_file(row, [first], "world_201.xml")
    assert path is None and "other bytes" in problem
