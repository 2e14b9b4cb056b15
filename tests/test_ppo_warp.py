"""`dynabarn-train ppo --env-backend warp` on Warp's CPU device: a few iterations train, a
run resumes from its checkpoint, and the policy drives on the C engine as `--planner ppo`."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
pytest.importorskip("mujoco_warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
pytest.importorskip("torch")

BIN = Path(sys.executable).parent
SMALL = ["--device", "cpu", "--num-envs", "2", "--rollout", "4", "--epochs", "1", "--minibatches", "2"]


def _train(out: Path, iterations: int) -> subprocess.CompletedProcess:
    command = [str(BIN / "dynabarn-train"), "ppo", "--world", "137", *SMALL, "--iterations", str(iterations)]
    return subprocess.run([*command, "--out", str(out)], capture_output=True, text=True, timeout=900)


def test_ppo_trains_resumes_and_its_policy_drives_on_the_c_engine(tmp_path):
    out = tmp_path / "ppo"
    done = _train(out, 2)
    assert done.returncode == 0, done.stderr[-2000:]
    history = json.loads((out / "history.json").read_text())
    assert [h["iteration"] for h in history] == [1, 2] and history[-1]["steps"] == 2 * 2 * 4
    assert all(abs(h["policy_loss"]) < 1e3 and h["value_loss"] >= 0 for h in history)
    done = _train(out, 3)  # the same command with more iterations goes on from the checkpoint
    assert done.returncode == 0, done.stderr[-2000:]
    resumed = json.loads((out / "history.json").read_text())
    assert resumed[:2] == history and resumed[2]["iteration"] == 3
    run = subprocess.run(
        [str(BIN / "dynabarn-run"), "--world", "137", "--planner", "ppo", "--policy", str(out / "policy.pt"),
         "--no-log", "--json"],
        capture_output=True,
        text=True,
        timeout=600,
    )  # fmt: skip
    result = json.loads(run.stdout)
    assert result["outcome"] in ("success", "collision", "timeout") and result["planner"] == "ppo", result
    assert result["planner_config"]["kind"] == "ppo"


def test_ppo_without_a_policy_on_a_missing_device_or_over_a_damaged_checkpoint_is_one_line(tmp_path):
    run = subprocess.run(
        [str(BIN / "dynabarn-run"), "--world", "137", "--planner", "ppo", "--no-log"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1 and "policy" in run.stderr, run.stderr
    train = subprocess.run(
        [str(BIN / "dynabarn-train"), "ppo", "--device", "cuda:7", "--out", "/nonexistent/x"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert train.returncode == 2 and len(train.stderr.strip().splitlines()) == 1, train.stderr
    assert "cuda:7" in train.stderr
    (tmp_path / "checkpoint.pt").write_bytes(b"garbage")
    (tmp_path / "history.json").write_text("[]")
    resumed = _train(tmp_path, 1)
    assert resumed.returncode == 2 and len(resumed.stderr.strip().splitlines()) == 1, resumed.stderr
    assert "cannot resume" in resumed.stderr and (tmp_path / "checkpoint.pt").read_bytes() == b"garbage"


def test_ppo_trains_on_a_procedural_splits_worlds_and_records_which(tmp_path):
    """`--split train`: the batch holds the split's first worlds (never an evaluation set's)."""
    out = tmp_path / "ppo"
    command = [str(BIN / "dynabarn-train"), "ppo", "--split", "train", "--procedural-worlds", "2", *SMALL]
    command += ["--iterations", "1", "--out", str(out)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    notes = __import__("torch").load(out / "policy.pt", weights_only=True)["notes"]
    assert (notes["split"], notes["procedural_worlds"], notes["device"]) == ("train", 2, "cpu"), notes
    bad = subprocess.run(
        [str(BIN / "dynabarn-train"), "ppo", "--difficulty", "hard", *SMALL, "--out", str(tmp_path / "x")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1, bad.stderr
    assert "--difficulty chooses within --world-set" in bad.stderr
