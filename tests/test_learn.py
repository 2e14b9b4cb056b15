"""Gymnasium environment, behaviour cloning, TD3 and the learned planners (learn extra)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from tests.conftest import require

gymnasium = require("gymnasium", "learn")
torch = require("torch", "learn")

import dynabarn.learn  # noqa: E402  (registers DynaBARN-v0)
from dynabarn.cli import demos_main, train_main  # noqa: E402
from dynabarn.errors import DynabarnError  # noqa: E402
from dynabarn.metrics import Outcome  # noqa: E402
from dynabarn.planners import get_planner  # noqa: E402
from dynabarn.planners.learned.models import Actor, load_policy  # noqa: E402
from dynabarn.planners.learned.spaces import action_to_command, command_to_action  # noqa: E402
from dynabarn.protocol import get_protocol  # noqa: E402
from dynabarn.recording import McapRecorder  # noqa: E402
from dynabarn.sim import run_episode  # noqa: E402
from dynabarn.worldset import resolve_world  # noqa: E402


def test_env_passes_gymnasium_checker():
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make(dynabarn.learn.ENV_ID, worlds=[0, 100, 200], world_set="dynabarn300")
    check_env(env.unwrapped)
    obs, info = env.reset(seed=3)
    assert obs.shape == (722,) and obs.dtype == np.float32 and env.observation_space.contains(obs)
    assert info["world"] in {"world_000", "world_100", "world_200"}


def test_env_is_deterministic_and_reports_reward_terms():
    env = gymnasium.make(dynabarn.learn.ENV_ID, world_set="dynabarn300", worlds=[0])
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=7)
        trace = [obs]
        for _ in range(30):
            obs, _, _, _, info = env.step(np.array([0.5, 0.0], np.float32))
            trace.append(obs)
        runs.append(np.array(trace))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert {"reward_progress", "reward_time", "reward_collision", "reward_success"} <= info.keys()
    assert info["reward_progress"] > 0.05  # driving at the goal makes progress


def test_env_episode_ends_with_success_reward():
    env = gymnasium.make(dynabarn.learn.ENV_ID, world_set="dynabarn300", worlds=[0])
    env.reset(seed=1, options={"trial_seed": 0})
    total, done = 0.0, False
    steps = 0
    while not done:
        _, r, term, trunc, info = env.step(command_to_action(2.0, 0.0))
        total += r
        done = term or trunc
        steps += 1
    assert info["outcome"] == "success" and term and info["reward_success"] == 20.0
    assert total > 20.0 + 18.0 - 0.01 * steps - 1e-6  # progress of ~19 m along the plan


def test_vector_envs_step_together():
    envs = gymnasium.vector.SyncVectorEnv(
        [lambda: gymnasium.make(dynabarn.learn.ENV_ID, world_set="dynabarn300", worlds=[0, 1])] * 2
    )
    obs, _ = envs.reset(seed=0)
    obs, r, _, _, _ = envs.step(np.zeros((2, 2), np.float32))
    assert obs.shape == (2, 722) and r.shape == (2,)
    envs.close()


def test_action_mapping_round_trip():
    v, w = action_to_command(np.array([-1.0, 1.0]))
    assert (v, w) == pytest.approx((-0.5, 3.14))
    a = command_to_action(np.array([0.75, 2.0]), np.array([0.0, -1.57]))
    np.testing.assert_allclose(a, [[0.0, 0.0], [1.0, -0.5]], atol=1e-6)


def test_networks_have_the_papers_shape():
    actor = Actor()
    sizes = [m.out_features for m in actor.modules() if isinstance(m, torch.nn.Linear)]
    assert sizes == [512, 256, 128, 64, 32, 2]
    out = actor(torch.zeros(4, 722))
    assert out.shape == (4, 2) and torch.all(out.abs() <= 1)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    d = tmp_path_factory.mktemp("bc")
    for w in (0, 1):
        run_episode(
            resolve_world(w),
            get_planner("oracle"),
            get_protocol("barn"),
            seed=0,
            observers=[McapRecorder(d / f"{w}.mcap")],
        )
    out = d / "ds.npz"
    assert demos_main(["export", str(d), "--dataset", str(out)]) == 0
    return out


def test_bc_fits_a_small_dataset(dataset, tmp_path, capsys):
    assert train_main(["bc", "--data", str(dataset), "--out", str(tmp_path / "bc"), "--epochs", "60"]) == 0
    out = tmp_path / "bc" / "policy.pt"
    line = capsys.readouterr().out
    first, last = (float(x) for x in line.split("loss ")[1].split(" -> "))
    assert last < 0.5 * first
    actor, header = load_policy(out)
    assert header["kind"] == "bc"
    from dynabarn.demos.dataset import load_dataset

    ds = load_dataset(dataset)
    obs = torch.from_numpy(np.concatenate([ds["scans"], ds["local_goal"]], axis=1))
    pred = actor(obs).detach().numpy()
    target = command_to_action(ds["actions"][:, 0], ds["actions"][:, 1])
    assert np.mean((pred - target) ** 2) < 0.05
    # The trained policy drives as a planner.
    r = run_episode(resolve_world(0), get_planner("bc", policy=str(out)), get_protocol("barn"), seed=0)
    assert r.outcome is not Outcome.ERROR


TD3_ARGV = [
    "td3",
    "--set",
    "dynabarn300",
    "--difficulty",
    "easy",
    "--steps",
    "400",
    "--eval-every",
    "200",
    "--eval-episodes",
    "1",
    "--demos",
    "2",
    "--bc-epochs",
    "1",
    "--critic-warmup",
    "4",
    "--threads",
    "1",
    "--start-steps",
    "300",
]


@pytest.mark.slow
def test_short_td3_run_trains_saves_and_resumes(tmp_path, capsys):
    """Demonstrations, behaviour cloning, critic warm-up, TD3, checkpoints with the whole
    state; running the same command again resumes (no new demonstrations, no new steps)."""
    from dynabarn.learn.replay_buffer import ReplayBuffer

    out = tmp_path / "td3"
    # A 4 s time limit from the start: episodes end within the run whatever the policy does.
    protocol = get_protocol("barn").to_dict() | {"name": "short", "time_limit": 4.0, "timer_start_distance": 0.0}
    (tmp_path / "short.json").write_text(json.dumps(protocol))
    argv = [*TD3_ARGV, "--protocol", str(tmp_path / "short.json"), "--out", str(out)]
    assert train_main(argv) == 0
    for name in (
        "policy.pt",
        "learning_curve.png",
        "training.json",
        "train.log",
        "state.pt",
        "replay.npz",
        "demos.npz",
        "checkpoint_00000200.pt",
        "checkpoint_00000400.pt",
    ):
        assert (out / name).is_file(), name
    _, header = load_policy(out / "policy.pt")
    assert header["kind"] == "td3" and header["notes"]["steps"] == 400
    log = (out / "train.log").read_text()
    assert "demonstrations {'timeout': 2} (80 transitions)" in log and '"step": 400' in log
    # The replay buffer holds true transitions: an episode's last row leads to its final
    # observation, not to the next episode's first (same-step autoreset), so rows whose
    # next observation is not the following row's are exactly the finished episodes.
    buf = ReplayBuffer.load(out / "replay.npz")
    assert len(buf) == 400
    breaks = [i for i in range(len(buf) - 1) if not np.array_equal(buf.next_obs[i], buf.obs[i + 1])]
    episodes = json.loads((out / "training.json").read_text())["episodes"]
    assert len(breaks) >= 1 and len(breaks) in (episodes, episodes - 1)
    # Interrupted after its last checkpoint: the same command finishes from the saved state.
    weights = torch.load(out / "policy.pt", weights_only=True)["state_dict"]
    (out / "policy.pt").unlink()
    assert train_main(argv) == 0
    resumed = torch.load(out / "policy.pt", weights_only=True)["state_dict"]
    assert all(torch.equal(weights[k], resumed[k]) for k in weights)
    assert "resumed at step 400" in (out / "train.log").read_text()
    # Another configuration into the same folder is refused.
    assert train_main([*argv, "--seed", "3"]) == 2
    assert "another configuration" in capsys.readouterr().err


def test_train_options_are_the_configurations_fields_written_once():
    from dataclasses import asdict

    from dynabarn.cli.train import build_parser
    from dynabarn.learn.configs import DaggerConfig, TD3Config, cli_options

    for command, config in (("td3", TD3Config), ("dagger", DaggerConfig)):
        args = build_parser().parse_args([command, "--out", "x"])
        offered = cli_options(config)
        assert len(offered) >= 10
        for name, *_ in offered:
            assert getattr(args, name) == asdict(config())[name], (command, name)
    # The configurations load without PyTorch (a fresh interpreter: nothing else loaded it).
    probe = "import sys, dynabarn.learn.configs; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "False", out.stderr


@pytest.mark.parametrize("planner", ["bc", "td3"])
def test_shipped_policies_complete_an_episode(planner):
    r = run_episode(resolve_world(0), get_planner(planner), get_protocol("barn"), seed=0)
    assert r.outcome in (Outcome.SUCCESS, Outcome.COLLISION, Outcome.TIMEOUT)
    assert r.n_ticks > 5


@pytest.mark.parametrize("planner", ["td3", "bc"])
def test_a_decision_runs_on_one_thread_and_leaves_the_processs_count(planner):
    """A decision is a batch of one: the network runs on one PyTorch thread (more only wait
    on each other on a busy machine), and the process's own count is back after each call."""
    p = get_planner(planner)
    seen: list[int] = []
    net = p.actor

    def counting(x):
        seen.append(torch.get_num_threads())
        return net(x)

    p.actor = counting
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        r = run_episode(resolve_world(0), p, get_protocol("barn"), seed=0)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    assert r.n_ticks >= 5 and len(seen) >= 5 and set(seen) == {1}


def test_the_dagger_planner_decides_on_one_blas_thread_and_leaves_the_processs_count():
    """numpy's BLAS runs each decision on one thread (a second only waits on a busy
    machine); the process's own count is back after the call."""
    p = get_planner("dagger")
    blas = p._blas
    forward = p._decide.forward
    seen: list[int] = []

    def counting(x):
        seen.extend(info["num_threads"] for info in blas.info())
        return forward(x)

    p._decide.forward = counting
    with blas.limit(limits=2):  # as an unconfigured process on 2 cores has (a sweep's workers have 1)
        before = [info["num_threads"] for info in blas.info()]
        r = run_episode(resolve_world(0), p, get_protocol("barn"), seed=0)
        assert [info["num_threads"] for info in blas.info()] == before
    assert r.n_ticks >= 5 and seen and set(seen) == {1}


def test_the_dagger_planner_decides_without_pytorch():
    """`dagger` reads its network into numpy when it loads (`NumpyStudent`): no decision
    calls PyTorch, so none waits on its threads, however many the process has."""
    p = get_planner("dagger")

    def refuse(*args, **kwargs):
        raise AssertionError("a decision called the PyTorch network")

    p.actor.net.forward = refuse
    p.actor.forward = refuse
    r = run_episode(resolve_world(0), p, get_protocol("barn"), seed=0)
    assert r.n_ticks >= 5


def test_bad_policy_files(tmp_path):
    with pytest.raises(DynabarnError, match="not found"):
        get_planner("bc", policy=str(tmp_path / "nope.pt"))
    bad = tmp_path / "bad.pt"
    torch.save({"something": 1}, bad)
    with pytest.raises(DynabarnError, match="not a dynabarn-policy-v1"):
        get_planner("td3", policy=str(bad))


def test_a_dagger_worker_keeps_only_its_current_environment():
    """A worker switches between the training and the validation split every iteration: the
    environment it leaves is closed and freed with its worlds' simulations (an `atexit`
    entry per environment once kept every one alive: ~100 MB a worker and iteration)."""
    import gc
    import weakref

    from dynabarn.learn import dagger_rollout
    from dynabarn.learn.configs import DaggerConfig

    cfg = DaggerConfig(workers=1, threads=1)
    first = dagger_rollout._env(cfg, "train")
    first.reset(options={"world_index": 0, "trial_seed": 0})
    assert first._sims
    gone = weakref.ref(first)
    del first
    try:
        second = dagger_rollout._env(cfg, "validation")
        gc.collect()
        assert gone() is None
        assert dagger_rollout._env(cfg, "validation") is second
    finally:
        dagger_rollout._close_env()
    assert "env" not in dagger_rollout._WORKER
