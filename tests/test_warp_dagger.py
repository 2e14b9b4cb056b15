"""DAgger's collection on the Warp backend (`learn.warp_dagger`) against the C engine's
(`dagger_rollout.episode`), on Warp's CPU device: the same episodes (worlds, trials, the
coin), the same labels where the teacher reads the true obstacles, the student's features
the same but for the few beams that graze an edge; and `dynabarn-train dagger
--env-backend warp` end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
pytest.importorskip("mujoco_warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
torch = pytest.importorskip("torch")

from dynabarn.learn.configs import DaggerConfig  # noqa: E402
from dynabarn.learn.dagger_rollout import episode, student_from  # noqa: E402
from dynabarn.learn.split import DEFAULT_PROFILE_SETS  # noqa: E402
from dynabarn.learn.warp_dagger import collect_on_warp  # noqa: E402
from dynabarn.planners.learned.student import student_for  # noqa: E402

PAPERS = list(DEFAULT_PROFILE_SETS)
"""The paper's and the release's profiles: worlds without a static field, which Warp's CPU
device steps several times faster than the tiers' (hundreds of standing cylinders)."""
FEATURE_TOLERANCE = 0.01
"""A feature entry (ranges scaled to [0, 1]) counts as different past this: the C engine's
scan carries its noise draw, Warp's its own (1 mm, i.e. 2e-4 of the scale)."""


def test_the_teachers_episodes_on_warp_are_the_c_engines():
    """The oracle teacher drives (beta 1) three of the split's worlds with two environments
    on two hosts (this process and a spawned one; one environment plays two episodes in
    turn, each cut by max_steps): the same worlds, trials, outcomes and steps as the C
    collection, every label equal (measured: all of them), and at most 0.1 % of the feature
    entries past the tolerance (measured: 3 of 195,120)."""
    cfg = DaggerConfig(max_steps=60, workers=1, threads=1, teacher="oracle_present", tracks=0, profile_sets=PAPERS)
    ks = [0, 1, 2]
    warp = collect_on_warp(cfg, ks, beta=1.0, actor=None, device="cpu", num_envs=2, workers=2)
    c = [episode(cfg, "train", k, 1.0, None, True) for k in ks]
    assert [e.k for e in warp] == ks
    for a, b in zip(warp, c, strict=True):
        assert (a.fingerprint, a.difficulty, a.outcome, a.steps) == (b.fingerprint, b.difficulty, b.outcome, b.steps)
        assert a.teacher_share == b.teacher_share == 1.0
        assert a.features.shape == b.features.shape and a.features.dtype == np.float16
        assert np.array_equal(a.labels, b.labels), a.k
        off = np.abs(a.features.astype(np.float64) - b.features.astype(np.float64)) > FEATURE_TOLERANCE
        assert off.sum() <= 0.001 * off.size, (a.k, int(off.sum()))


def test_the_student_drives_where_the_coin_says_and_the_teacher_labels_every_state():
    cfg = DaggerConfig(max_steps=30, workers=1, threads=1, teacher="oracle_present", tracks=0, profile_sets=PAPERS)
    torch.manual_seed(0)
    weights = {k: v.cpu() for k, v in student_for(cfg.features(), None, cfg.encoder).state_dict().items()}
    actor = student_from(cfg, weights)
    warp = collect_on_warp(cfg, [5, 6], beta=0.0, actor=actor, device="cpu", num_envs=2)
    c = [episode(cfg, "train", k, 0.0, actor, True) for k in (5, 6)]
    for a, b in zip(warp, c, strict=True):
        assert a.teacher_share == b.teacher_share == 0.0  # beta 0: the student alone
        assert len(a.labels) == a.steps <= cfg.max_steps and a.outcome in ("success", "collision", "timeout", "cut")
        assert a.fingerprint == b.fingerprint
        # The same untrained student from (nearly) the same features drives (nearly) the same
        # way: most of the first labels are the C collection's (a near tie between two of the
        # teacher's commands may fall either way on each engine's own noise draw).
        same = np.all(a.labels[:10] == b.labels[:10], axis=1)
        assert same.sum() >= 5, (a.k, same)


def test_dagger_trains_with_its_collection_on_warp(tmp_path):
    from dynabarn.cli.train import train_main

    out = tmp_path / "run"
    args = ["dagger", "--out", str(out), "--episodes", "2", "--max-steps", "20", "--updates", "5", "--iterations", "1"]
    args += ["--validation-episodes", "1", "--workers", "1", "--threads", "1", "--device", "cpu"]
    args += ["--profiles", ",".join(PAPERS)]
    assert train_main([*args, "--env-backend", "warp", "--warp-envs", "2"]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["env_backend"] == "warp" and config["warp_envs"] == 2
    log = [json.loads(line) for line in (out / "train.log").read_text().splitlines()]
    assert log[0]["collection"]["episodes"] == 2 and 0 < log[0]["rows"] <= 40  # two episodes, each cut at 20 steps
    assert (out / "policy.pt").is_file()
