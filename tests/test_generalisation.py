"""Issue 30: the procedural split and its refusal, DAgger's aggregation and a short run
that improves, the student planner (learn extra)."""

import json

import numpy as np
import pytest

from tests.conftest import require

gymnasium = require("gymnasium", "learn")
torch = require("torch", "learn")

from dynabarn.cli import train_main  # noqa: E402
from dynabarn.errors import DynabarnError  # noqa: E402
from dynabarn.learn.dagger import DaggerConfig, Dataset, _identity, fit, teacher_classes  # noqa: E402
from dynabarn.learn.dagger_rollout import _job, episode  # noqa: E402
from dynabarn.learn.env import DynaBARNEnv, shipped_fingerprints  # noqa: E402
from dynabarn.learn.split import ProceduralWorlds, reserved_fingerprints  # noqa: E402
from dynabarn.mjcf import read_world  # noqa: E402
from dynabarn.planners import get_planner  # noqa: E402
from dynabarn.planners.learned.features import FeatureConfig, Features  # noqa: E402
from dynabarn.planners.learned.spaces import command_to_action  # noqa: E402
from dynabarn.planners.learned.student import StudentActor, load_student, save_student  # noqa: E402
from dynabarn.protocol import get_protocol  # noqa: E402
from dynabarn.sim import Episode, Simulation, run_episode  # noqa: E402
from dynabarn.worlds.fingerprint import world_fingerprint  # noqa: E402
from dynabarn.worldset import resolve_world  # noqa: E402


def test_fingerprint_ignores_names_and_order_but_not_motion(tmp_path):
    import dataclasses

    w = read_world(resolve_world(137))
    fp = world_fingerprint(w)
    renamed = dataclasses.replace(w, name="other", world_id=5, seed=9, obstacles=tuple(reversed(w.obstacles)))
    assert world_fingerprint(renamed) == fp
    o = w.obstacles[0]
    moved_xy = o.trajectory.xy.copy()
    moved_xy[0, 0] += 0.01
    moved = dataclasses.replace(o, trajectory=dataclasses.replace(o.trajectory, xy=moved_xy))
    assert world_fingerprint(dataclasses.replace(w, obstacles=(moved, *w.obstacles[1:]))) != fp


def test_procedural_worlds_are_reproducible_fresh_and_never_shipped(tmp_path):
    a = ProceduralWorlds(tmp_path / "a", seed=3)
    b = ProceduralWorlds(tmp_path / "b", seed=3)
    other = ProceduralWorlds(tmp_path / "c", seed=4)
    val = ProceduralWorlds(tmp_path / "d", split="validation", seed=3)
    fps = [a.world(k).fingerprint for k in range(12)]
    assert fps == [b.world(k).fingerprint for k in range(12)]
    assert a.world(5).path.read_bytes() == b.world(5).path.read_bytes()
    assert len(set(fps)) == 12
    assert not set(fps) & {other.world(k).fingerprint for k in range(12)}
    assert not set(fps) & {val.world(k).fingerprint for k in range(12)}
    assert not set(fps) & shipped_fingerprints()
    assert {a.world(k).difficulty for k in range(12)} == {"easy", "medium", "hard"}
    # A reserved world is never drawn: reserve world 0's fingerprint, draw again.
    reserved = ProceduralWorlds(tmp_path / "e", seed=3, reserved=frozenset({fps[0]}))
    assert reserved.world(0).fingerprint != fps[0]
    assert reserved.world(1).fingerprint == fps[1]
    assert len(reserved_fingerprints()) == 300


def _student_file(tmp_path, trained: list[str]):
    cfg = FeatureConfig(history=1, tracks=2, velocity=True)
    actor = StudentActor(cfg.size())
    path = tmp_path / "student.pt"
    save_student(actor, path, features=cfg, trained_on={"split": "test", "fingerprints": trained}, notes={})
    return path


def test_student_planner_refuses_a_world_it_trained_on(tmp_path):
    seen = Simulation(resolve_world(137))
    policy = _student_file(tmp_path, [seen.world_fingerprint])
    planner = get_planner("dagger", policy=str(policy))
    with pytest.raises(DynabarnError, match="trained on this world"):
        run_episode(resolve_world(137), planner, get_protocol("barn"), seed=0)
    # The same world under another name and file is still refused.
    copy = tmp_path / "renamed.xml"
    copy.write_bytes(resolve_world(137).read_bytes())
    with pytest.raises(DynabarnError, match="trained on this world"):
        run_episode(copy, get_planner("dagger", policy=str(policy)), get_protocol("barn"), seed=0)
    result = run_episode(resolve_world(138), get_planner("dagger", policy=str(policy)), get_protocol("barn"), seed=0)
    assert result.outcome is not None


def test_dagger_cli_refusal_is_one_line(tmp_path, capsys):
    from dynabarn.cli import run_main

    policy = _student_file(tmp_path, [Simulation(resolve_world(12)).world_fingerprint])
    code = run_main(["--world", "12", "--planner", "dagger", "--policy", str(policy), "--no-log"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "trained on this world" in err[0]


def test_student_file_round_trip_and_bad_headers(tmp_path):
    path = _student_file(tmp_path, ["abc"])
    _, features, header = load_student(path)
    assert features.history == 1 and features.tracks == 2 and header["trained_on"]["fingerprints"] == ["abc"]
    blob = torch.load(path, weights_only=True)
    blob["n_inputs"] = 5
    bad = tmp_path / "bad.pt"
    torch.save(blob, bad)
    with pytest.raises(DynabarnError, match="inputs"):
        load_student(bad)


def test_features_history_and_tracks_see_motion():
    sim = Simulation(resolve_world(250))
    ep = Episode(sim, get_protocol("barn"), seed=1)
    cfg = FeatureConfig(history=2, history_every=1, velocity=True, tracks=4)
    f = Features(cfg)
    f.reset(ep.info)
    rows = []
    for _ in range(12):
        obs = ep.observe()
        rows.append(f(obs))
        ep.apply(0.0, 0.0)  # standing still: only the obstacles move
    rows = np.array(rows)
    assert rows.shape == (12, cfg.size())
    hist = rows[:, 722 : 722 + 180]
    # The first tick's history repeats its own frame; later ticks hold earlier frames.
    pooled_now = np.pad(rows[:, :720], ((0, 0), (0, 0))).reshape(12, 180, 4).min(axis=2)
    assert np.allclose(hist[0], pooled_now[0]) and np.allclose(hist[5], pooled_now[4])
    tracks = rows[:, -4 * 6 :].reshape(12, 4, 6)
    assert tracks[-1, :, 5].sum() >= 1  # some obstacle is tracked
    assert np.abs(tracks[-1, :, 2:4]).max() > 0.05  # and moves


@pytest.mark.parametrize("teacher", ["oracle_present", "predictive"])
def test_dagger_aggregates_student_states_with_teacher_labels(tmp_path, teacher):
    cfg = DaggerConfig(episodes=2, validation_episodes=1, updates=2, workers=1, max_steps=60, teacher=teacher)
    actor = StudentActor(cfg.features().size())
    data = episode(cfg, "train", 0, 0.0, actor, label=True)  # beta 0: the student drives every step
    assert data.teacher_share == 0.0 and len(data.features) == data.steps
    # Replay the episode: the student drove (its actions), the labels are the teacher's.
    env = DynaBARNEnv(split="train", split_seed=cfg.seed, split_profile_sets=tuple(cfg.profile_sets))
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 0, 0]))
    env.reset(options={"world_index": 0, "trial_seed": int(rng.integers(2**31)), "privileged": True})
    teacher = get_planner(cfg.teacher)
    teacher.reset(env.episode.info)
    feats = Features(cfg.features())
    feats.reset(env.episode.info)
    for t in range(min(20, data.steps)):
        obs = env.observation
        x = feats(obs)
        np.testing.assert_array_equal(x.astype(np.float16), data.features[t])
        np.testing.assert_array_equal(command_to_action(*teacher.act(obs)), data.labels[t])
        with torch.no_grad():
            env.step(actor(torch.from_numpy(x[None]).float()).numpy()[0])
    env.close()
    ds = Dataset(tmp_path / "data")
    n0 = ds.add(0, [data])
    n1 = ds.add(1, [data, data])
    x, y = ds.arrays()
    assert (n0, n1, len(x), len(y)) == (data.steps, 2 * data.steps, 3 * data.steps, 3 * data.steps)
    again = Dataset(tmp_path / "data")
    again.load(2)
    assert np.array_equal(again.arrays()[0], x)


@pytest.mark.slow
def test_short_dagger_run_learns_saves_resumes_and_drives(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["dagger", "--out", str(out), "--episodes", "4", "--max-steps", "80", "--updates", "150"]
    args += ["--batch-size", "128", "--validation-episodes", "2", "--workers", "2", "--threads", "1"]
    assert train_main([*args, "--iterations", "1"]) == 0
    assert train_main([*args, "--iterations", "2", "--final-updates", "50"]) == 0  # resumes after iteration 0
    log = [json.loads(line) for line in (out / "train.log").read_text().splitlines()]
    final = log.pop()["final"]
    assert final["updates"] == 50 and final["validation"]["episodes"] == 2
    assert [e["iteration"] for e in log] == [0, 1]
    assert log[0]["beta"] == 1.0 and log[1]["beta"] == 0.5 and log[1]["dataset"] > log[0]["dataset"]
    # The fit (the classifier, the default head) reduces the imitation loss from an
    # untrained network's cross-entropy over the teacher's 42 commands (ln 42 = 3.7) by a
    # wide margin.
    assert log[1]["loss"] < 2.0
    _, features, header = load_student(out / "policy.pt")
    assert header["trained_on"]["split"] == "procedural-train" and header["trained_on"]["worlds"] == 8
    assert features.tracks == 16 and features.history == 2
    result = run_episode(resolve_world(3), get_planner("dagger", policy=str(out / "policy.pt")), get_protocol("barn"))
    assert result.outcome is not None
    # A damaged checkpoint is refused in one line, not unpickled.
    (out / "state.pt").write_bytes(b"not a checkpoint")
    capsys.readouterr()
    assert train_main([*args, "--iterations", "3"]) == 2
    assert "cannot resume from its checkpoint" in capsys.readouterr().err


def test_a_teacher_that_is_not_offered_is_refused_where_the_run_is_configured():
    with pytest.raises(DynabarnError, match="teacher 'oracle': use one of oracle_present, predictive"):
        DaggerConfig(teacher="oracle")


def test_classifier_student_classifies_the_teachers_grid_and_keeps_it_in_its_file(tmp_path):
    cfg = DaggerConfig(head="classify", workers=1)
    classes = teacher_classes(cfg)
    oracle = get_planner(cfg.teacher).cfg
    assert classes.shape == (len(oracle.v_samples) * len(oracle.w_samples), 2)
    actor = StudentActor(cfg.features().size(), classes=classes)
    # The teacher's own commands map onto their classes exactly; anything else is refused.
    v, w = oracle.v_samples[2], oracle.w_samples[5]
    label = actor.class_labels(command_to_action(np.array([v]), np.array([w])))
    np.testing.assert_array_equal(classes[label[0]], command_to_action(v, w))
    with pytest.raises(DynabarnError, match="grid"):
        actor.class_labels(np.array([[0.33, -0.41]], np.float32))
    # Acting drives the likeliest class's command, never an average of two.
    x = torch.randn(16, cfg.features().size())
    with torch.no_grad():
        acts = actor.act(x).numpy()
        likeliest = actor(x).argmax(dim=-1).numpy()
    np.testing.assert_array_equal(acts, classes[likeliest])
    # The file keeps the head and the classes; a student loaded from it acts the same.
    path = save_student(actor, tmp_path / "c.pt", features=cfg.features(), trained_on={"fingerprints": []}, notes={})
    again, _, header = load_student(path)
    assert header["head"] == "classify" and again.head == "classify"
    with torch.no_grad():
        np.testing.assert_array_equal(again.act(x).numpy(), acts)
    blob = torch.load(path, weights_only=True)
    blob["classes"] = [[0.0, 0.0, 0.0]] * 42
    torch.save(blob, tmp_path / "bad.pt")
    with pytest.raises(DynabarnError, match="malformed student header"):
        load_student(tmp_path / "bad.pt")
    # A DAgger worker rebuilds the classifier from its weights alone, and it drives.
    weights = {k: t.clone() for k, t in actor.state_dict().items()}
    (data,) = _job(DaggerConfig(head="classify", max_steps=30, encoder="mlp"), "train", [0], 0.0, weights, False)
    assert data.steps > 0 and data.outcome in ("success", "collision", "timeout", "cut", "error")


def test_a_run_from_before_the_classifier_resumes_as_the_regression_it_was():
    from dataclasses import asdict

    old = {k: v for k, v in asdict(DaggerConfig()).items() if k != "head"}  # its config.json had no head
    assert _identity(old)["head"] == "regress" and DaggerConfig().head == "classify"
    assert _identity(old) == _identity(asdict(DaggerConfig(head="regress")))


def test_the_default_run_is_the_shipped_students_recipe_and_the_first_students_run_reads_as_it_was():
    """`dynabarn-train dagger --out DIR` trains what `dagger` drives (the committed run of
    `dagger_predictive.pt`, apart from where it ends and how it ran); the first student's
    run, written before `--encoder`, still reads as the flat network it trained."""
    from dataclasses import asdict
    from pathlib import Path

    results = Path(__file__).resolve().parents[1] / "results"
    shipped = json.loads((results / "dagger_set_predictive_training" / "config.json").read_text())
    assert _identity(shipped) == _identity(asdict(DaggerConfig()))
    first = json.loads((results / "dagger_training" / "config.json").read_text())
    assert "encoder" not in first
    assert _identity(first)["encoder"] == "mlp" and _identity(first)["teacher"] == "oracle_present"
    assert _identity(first) != _identity(asdict(DaggerConfig()))


def test_classifier_fit_learns_a_rule_with_cross_entropy():
    cfg = DaggerConfig(head="classify", updates=300, batch_size=128, lr=3e-3)
    classes = teacher_classes(cfg)
    rng = np.random.default_rng(0)
    x = rng.normal(size=(2000, 20)).astype(np.float16)
    # The teacher's class is a function of the state: left of zero one command, right another.
    y = np.where(x[:, :1] > 0, classes[3], classes[40]).astype(np.float32)
    torch.manual_seed(0)
    actor = StudentActor(20, hidden=(32,), classes=classes)
    opt = torch.optim.Adam(actor.parameters(), lr=cfg.lr)
    loss = fit(actor, opt, x, y, cfg, seed=0)
    # Untrained: about ln(42) = 3.7; a learned two-way rule: near 0.
    assert loss < 0.3
    with torch.no_grad():
        acts = actor.act(torch.from_numpy(x[:200]).float()).numpy()
    assert np.mean(np.all(acts == y[:200], axis=1)) > 0.95
