"""The `set` student (issue 44): tracks read as a set, scans by convolution, its file, the
training split's tiers, and a CPU run's policy bytes whatever its workers and device."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from dynabarn.errors import DynabarnError  # noqa: E402
from dynabarn.learn.configs import DaggerConfig  # noqa: E402
from dynabarn.learn.split import ProceduralWorlds  # noqa: E402
from dynabarn.planners.learned.features import TRACK_FIELDS, FeatureConfig  # noqa: E402
from dynabarn.planners.learned.student import load_student, save_student, student_for  # noqa: E402

FEATURES = FeatureConfig(history=2, velocity=True, tracks=8)
CLASSES = np.stack(np.meshgrid(np.linspace(-1, 1, 6), np.linspace(-1, 1, 7), indexing="ij"), -1).reshape(-1, 2)


def _student(seed: int = 0):
    torch.manual_seed(seed)
    return student_for(FEATURES, CLASSES.astype(np.float32), "set").double().eval()


def _inputs(rng: np.random.Generator, batch: int = 4, present: int = 5) -> np.ndarray:
    x = rng.uniform(0.0, 1.0, (batch, FEATURES.size()))
    a, b = FEATURES.layout()["tracks"]
    slots = rng.uniform(-1.0, 1.0, (batch, FEATURES.tracks, TRACK_FIELDS))
    slots[:, :, TRACK_FIELDS - 1] = 0.0
    slots[:, :present, TRACK_FIELDS - 1] = 1.0
    slots[:, present:, : TRACK_FIELDS - 1] = 0.0  # empty slots read zero, as `Features` writes them
    x[:, a:b] = slots.reshape(batch, -1)
    return x


def _out(actor, x: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        return actor(torch.from_numpy(x)).numpy()


def test_the_set_encoder_does_not_depend_on_the_order_of_the_tracks():
    actor, rng = _student(), np.random.default_rng(1)
    x = _inputs(rng)
    a, b = FEATURES.layout()["tracks"]
    for _ in range(5):
        y = x.copy()
        slots = y[:, a:b].reshape(len(y), FEATURES.tracks, TRACK_FIELDS)
        y[:, a:b] = slots[:, rng.permutation(FEATURES.tracks)].reshape(len(y), -1)  # empty slots move too
        assert not np.array_equal(x, y)
        np.testing.assert_allclose(_out(actor, y), _out(actor, x), rtol=0, atol=1e-12)


def test_the_set_encoder_reads_each_input_where_the_layout_puts_it():
    actor, rng = _student(), np.random.default_rng(2)
    x = _inputs(rng, present=3)
    lay = FEATURES.layout()
    a, _ = lay["tracks"]
    base = _out(actor, x)
    # What an empty slot holds beyond its flag is not read; a present track's position is.
    empty = x.copy()
    empty[:, a + 5 * TRACK_FIELDS : a + 5 * TRACK_FIELDS + 4] = 0.7
    np.testing.assert_array_equal(_out(actor, empty), base)
    moved = x.copy()
    moved[:, a] += 0.3
    assert np.abs(_out(actor, moved) - base).max() > 1e-6
    # The current scan, each history frame, the goal and the velocity all count (and the
    # map, where given: `test_the_map_channel_is_read`).
    for lo, hi in ((0, 720), lay["history"], (720, 722), lay["velocity"]):
        y = x.copy()
        y[:, lo:hi] = rng.uniform(0.0, 1.0, (len(y), hi - lo))
        assert np.abs(_out(actor, y) - base).max() > 1e-6, (lo, hi)


def test_the_map_channel_is_read():
    features = FeatureConfig(history=2, static_map=True, velocity=True, tracks=8)
    torch.manual_seed(0)
    actor = student_for(features, CLASSES.astype(np.float32), "set").double().eval()
    rng = np.random.default_rng(4)
    x = rng.uniform(0.0, 1.0, (4, features.size()))
    a, b = features.layout()["static_map"]
    y = x.copy()
    y[:, a:b] = rng.uniform(0.0, 1.0, (4, b - a))
    assert np.abs(_out(actor, y) - _out(actor, x)).max() > 1e-6


def test_a_set_student_file_keeps_its_encoder_and_acts_the_same(tmp_path):
    actor = _student(3)
    path = save_student(actor, tmp_path / "s.pt", features=FEATURES, trained_on={"fingerprints": []}, notes={})
    again, features, header = load_student(path)
    assert header["encoder"] == "set" and again.encoder == "set" and features == FEATURES
    x = torch.from_numpy(_inputs(np.random.default_rng(4)))
    with torch.no_grad():
        np.testing.assert_array_equal(again.double().act(x).numpy(), actor.act(x).numpy())
    # A flat student's file has no encoder field (the shipped one's bytes stay as they are).
    flat = student_for(FEATURES, None, "mlp")
    save_student(flat, tmp_path / "f.pt", features=FEATURES, trained_on={"fingerprints": []}, notes={})
    assert "encoder" not in load_student(tmp_path / "f.pt")[2]
    blob = torch.load(path, weights_only=True)
    blob["encoder"] = "transformer"
    torch.save(blob, tmp_path / "bad.pt")
    with pytest.raises(DynabarnError, match="malformed student header"):
        load_student(tmp_path / "bad.pt")


def test_the_training_split_draws_from_a_tiers_profile_and_refuses_an_unknown_name(tmp_path):
    worlds = ProceduralWorlds(tmp_path, profile_sets=("tier-mixed",))
    from dynabarn.mjcf import read_world

    spec = read_world(worlds.world(0).path)
    assert len(spec.layout.cylinders) > 10, "a tier-mixed training world has its static field"
    assert worlds.world(0).profile_set == "tier-mixed"
    with pytest.raises(DynabarnError, match="tier-nope"):
        DaggerConfig(profile_sets=["tier-nope"])


def test_fitting_on_cuda_without_one_is_one_line():
    from dynabarn.learn.dagger import fitting_device

    assert fitting_device("cpu") == "cpu"
    if torch.cuda.is_available():
        pytest.skip("this machine has a CUDA GPU")
    assert fitting_device("auto") == "cpu"
    with pytest.raises(DynabarnError, match="no CUDA GPU"):
        fitting_device("cuda")


@pytest.mark.slow
def test_a_cpu_runs_policy_bytes_do_not_depend_on_its_workers_or_device_choice(tmp_path):
    from dynabarn.cli.train import train_main

    args = ["dagger", "--iterations", "2", "--episodes", "2", "--max-steps", "30", "--updates", "5"]
    args += ["--batch-size", "32", "--validation-episodes", "1", "--threads", "1", "--encoder", "set"]
    auto = "cpu" if torch.cuda.is_available() else "auto"  # auto on a GPU machine would fit on the GPU
    digests = []
    for workers, device in (("1", "cpu"), ("2", auto)):
        out = tmp_path / f"run{workers}"
        assert train_main([*args, "--workers", workers, "--device", device, "--out", str(out)]) == 0
        digests.append(hashlib.sha256(Path(out / "policy.pt").read_bytes()).hexdigest())
    assert digests[0] == digests[1]


@pytest.mark.parametrize(
    ("encoder", "features", "classes"),
    [
        ("set", FEATURES, CLASSES),
        ("set", FeatureConfig(history=2, static_map=True, velocity=True, tracks=8), CLASSES),  # the map's channel
        ("set", FeatureConfig(static_map=True, history_pool=7), CLASSES),  # a map but no history frames
        ("set", FeatureConfig(history_pool=7), CLASSES),  # no history, velocity or tracks; 720 = 7 * 103 - 1
        ("set", FeatureConfig(history=3, history_pool=6, tracks=3), None),  # the regression head
        ("mlp", FEATURES, CLASSES),
        ("mlp", FeatureConfig(history=1, velocity=True), None),
        ("mlp", FeatureConfig(history=1, static_map=True), CLASSES),
    ],
)
def test_the_numpy_network_decides_as_the_pytorch_network(encoder, features, classes):
    """The `dagger` planner decides with `NumpyStudent`: its outputs within 1e-12 of the
    PyTorch network's in float64 (only the order of a matrix product's additions may
    differ) and the same commands chosen, on inputs with every count of tracks."""
    from dynabarn.planners.learned.numpy_student import NumpyStudent

    rng = np.random.default_rng(6)
    torch.manual_seed(5)
    actor = student_for(features, None if classes is None else classes.astype(np.float32), encoder).double().eval()
    decide = NumpyStudent(actor)
    n = features.size()
    x = rng.uniform(0.0, 1.0, (40, n))
    if features.tracks:
        a, b = features.layout()["tracks"]
        slots = rng.uniform(-1.0, 1.0, (40, features.tracks, TRACK_FIELDS))
        present = np.arange(features.tracks)[None, :] < rng.integers(0, features.tracks + 1, 40)[:, None]
        slots[..., TRACK_FIELDS - 1] = present
        slots[~present] = 0.0
        x[:, a:b] = slots.reshape(40, -1)
    with torch.no_grad():
        logits = actor(torch.from_numpy(x)).numpy()
        actions = actor.act(torch.from_numpy(x)).numpy()
    mine = np.array([decide.forward(row) for row in x])
    assert mine.shape == logits.shape
    np.testing.assert_allclose(mine, logits, rtol=0, atol=1e-12)
    chosen = np.array([decide(row) for row in x])
    if classes is None:  # tanh is numpy's and PyTorch's own: their last bits may differ
        np.testing.assert_allclose(chosen, actions, rtol=0, atol=1e-12)
    else:
        np.testing.assert_array_equal(chosen, actions)


@pytest.mark.parametrize(
    ("policy", "teacher", "encoder"),
    [
        ("dagger.pt", "oracle_present", "mlp"),
        ("dagger_set.pt", "oracle_present", "set"),
        ("dagger_predictive.pt", "predictive", "set"),
        ("dagger_map.pt", "predictive", "set"),
    ],
)
def test_each_shipped_student_names_its_teacher_and_drives(policy, teacher, encoder):
    """The package's students: each file says which teacher labelled its states and what
    network reads them, and drives an episode of a shipped world (none of them trained on one)."""
    from dynabarn.metrics import Outcome
    from dynabarn.planners import get_planner
    from dynabarn.planners.learned.policy import SHIPPED
    from dynabarn.protocol import get_protocol
    from dynabarn.sim import run_episode
    from dynabarn.worldset import resolve_world

    actor, features, header = load_student(SHIPPED / policy)
    assert header["notes"]["config"]["teacher"] == teacher and actor.encoder == encoder
    assert features.static_map is (policy == "dagger_map.pt")  # only the issue-57 student sees the map
    planner = get_planner("dagger", policy=str(SHIPPED / policy))
    result = run_episode(resolve_world(3), planner, get_protocol("barn"), seed=0)
    assert result.outcome in (Outcome.SUCCESS, Outcome.COLLISION, Outcome.TIMEOUT) and result.n_ticks > 5


def test_the_default_dagger_is_the_student_taught_by_predictive():
    """`dagger` without `policy=` drives `DEFAULT_STUDENT` (issue 44), and results name it by
    its place in the package, so they read the same wherever the package is installed."""
    from dynabarn.planners import get_planner

    config = get_planner("dagger").config()
    assert config["policy"] == "dynabarn/policies/dagger_predictive.pt"
    assert config["features"] == ["scan+goal", "history 2x0.2s", "velocity", "tracks 16"]
