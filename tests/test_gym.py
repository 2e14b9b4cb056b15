"""`dynabarn/DynaBARN-v0` as Gymnasium and Stable-Baselines3 users meet it: rendering,
RecordVideo, `is_success`, the time limit, argument checks, PPO on subprocess envs, and
the viewer window in human mode (Xvfb)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from tests.conftest import require

gymnasium = require("gymnasium", "learn")
require("torch", "learn")

from dynabarn.learn.env import episode_step_limit  # noqa: E402

FULL_SPEED_AHEAD = np.array([1.0, 0.0], dtype=np.float32)  # v = 2 m/s straight at the goal


def test_registered_under_the_namespace_with_the_protocols_longest_episode():
    spec = gymnasium.spec("dynabarn/DynaBARN-v0")
    assert spec.max_episode_steps == episode_step_limit("barn") == 2000
    assert gymnasium.spec("DynaBARN-v0").entry_point == spec.entry_point


def test_is_success_and_rgb_frames():
    # World 0 is crossed by driving straight at the goal (9.5 s, 96 control steps).
    env = gymnasium.make("dynabarn/DynaBARN-v0", world_set="dynabarn300", worlds=[0], render_mode="rgb_array")
    _, info = env.reset(seed=0, options={"trial_seed": 0})
    assert info["is_success"] is False
    first = env.render()
    assert first.shape == (480, 640, 3) and first.dtype == np.uint8
    for steps in range(1, 400):  # noqa: B007
        _, _, terminated, truncated, info = env.step(FULL_SPEED_AHEAD)
        if terminated or truncated:
            break
    assert terminated and not truncated and info["outcome"] == "success" and info["is_success"] is True
    assert 80 <= steps <= 110
    last = env.render()
    # The scene moved: the robot crossed the arena and the obstacles went on.
    assert np.abs(last.astype(int) - first.astype(int)).max() > 100
    # The obstacles' red is in the frame (not an empty or black image).
    red = (last[..., 0] > 150) & (last[..., 1] < 110) & (last[..., 2] < 110)
    assert red.sum() > 200
    env.close()


@pytest.mark.slow
def test_record_video_writes_an_episode(tmp_path):
    require("moviepy", "test")
    env = gymnasium.make("dynabarn/DynaBARN-v0", world_set="dynabarn300", worlds=[0], render_mode="rgb_array")
    env = gymnasium.wrappers.RecordVideo(env, str(tmp_path), episode_trigger=lambda k: True, disable_logger=True)
    env.reset(seed=0, options={"trial_seed": 0})
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(FULL_SPEED_AHEAD)
        done = terminated or truncated
    env.close()
    (video,) = tmp_path.glob("*.mp4")
    import imageio.v3 as iio

    frames = iio.imread(video, plugin="pyav") if _has_pyav() else iio.imread(video)
    assert 80 <= len(frames) <= 112  # one frame per control step plus the reset's


def _has_pyav() -> bool:
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"difficulty": "extreme"}, "difficulty 'extreme'"),
        ({"worlds": [1], "difficulty": "easy"}, "not both"),
        ({"worlds": [999]}, "[999] not in set"),
        ({"worlds": "0,1"}, "list of world ids"),
        ({"lookahead": float("nan")}, "lookahead"),
        ({"protocol": "nope"}, "unknown protocol"),
        ({"render_mode": "rgb"}, "render_mode 'rgb'"),
        ({"camera": "side"}, "camera 'side'"),
        ({"world_set": "/no/such/folder"}, "unknown world set"),
    ],
)
def test_bad_arguments_give_one_clear_error(kwargs, message):
    with pytest.raises(ValueError, match=None) as err:
        gymnasium.make("dynabarn/DynaBARN-v0", disable_env_checker=True, **kwargs)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_worlds_override_the_default_set():
    # 250 is not among paper60's ids; an explicit id chooses from all 300.
    env = gymnasium.make("dynabarn/DynaBARN-v0", worlds=[250])
    _, info = env.reset(seed=1)
    assert info["world_id"] == 250 and info["difficulty"] == "hard"
    env.close()


@pytest.mark.slow
def test_sb3_ppo_trains_on_subprocess_envs_and_evaluates():
    sb3 = require("stable_baselines3", "test")
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # Hard worlds: episodes end quickly (collisions), so SB3 sees finished episodes.
    kwargs = {"world_set": "dynabarn300", "worlds": [250, 260, 270]}
    # "module:id": each fresh worker process imports dynabarn.learn, which registers the id.
    venv = make_vec_env(
        "dynabarn.learn:dynabarn/DynaBARN-v0", n_envs=2, seed=0, env_kwargs=kwargs, vec_env_cls=SubprocVecEnv
    )
    try:
        model = sb3.PPO("MlpPolicy", venv, n_steps=512, batch_size=128, n_epochs=2, seed=0, device="cpu", verbose=0)
        model.learn(total_timesteps=2048)
        assert model.num_timesteps >= 2048
        # SB3 read `is_success` from the finished episodes (its success-rate log).
        assert len(model.ep_success_buffer) > 0
        assert all(isinstance(s, bool | np.bool_) for s in model.ep_success_buffer)
        mean, std = evaluate_policy(model, venv, n_eval_episodes=4, deterministic=True)
        assert np.isfinite(mean) and np.isfinite(std)
    finally:
        venv.close()


@pytest.mark.slow
def test_human_mode_opens_the_viewer_on_a_display(tmp_path, display):
    from tests.xwindow import find_window, no_window

    env = {**os.environ, "DISPLAY": display}
    env.pop("MUJOCO_GL", None)  # the viewer uses GLFW on the X display
    script = (
        "import gymnasium as gym, numpy as np, dynabarn.learn, time\n"
        "env = gym.make('dynabarn/DynaBARN-v0', world_set='dynabarn300', worlds=[0], render_mode='human')\n"
        "env.reset(seed=0, options={'trial_seed': 0})\n"
        "t = time.perf_counter()\n"
        "for _ in range(30): env.step(np.array([1.0, 0.0], dtype=np.float32))\n"
        "print('paced', round(time.perf_counter() - t, 1), flush=True)\n"
        "time.sleep(3)\n"
        "env.close()\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    window = find_window(env, process=proc)
    if not window:
        pytest.fail(no_window(proc))
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 0
    # 30 control steps of 0.1 s shown at real time.
    assert 2.5 <= float(out.split()[-1]) <= 6.0


def test_rgb_array_and_check_env_on_a_machine_without_a_display_choose_egl():
    """Headless and no MUJOCO_GL (MuJoCo picked GLFW when imported, which cannot open a
    context): the environment takes EGL itself, as the commands do, so rgb_array frames and
    Gymnasium's check_env work with nothing set."""
    from tests.conftest import run_headless

    code = (
        "import gymnasium, os, dynabarn.learn\n"
        "from gymnasium.utils.env_checker import check_env\n"
        "env = gymnasium.make('dynabarn/DynaBARN-v0', world_set='dynabarn300', worlds=[0], render_mode='rgb_array',"
        " width=64, height=48)\n"
        "env.reset(seed=0)\n"
        "frame = env.render()\n"
        "check_env(env.unwrapped, skip_render_check=False)\n"
        "print(frame.shape, int(frame.std() > 1), os.environ['MUJOCO_GL'])\n"
    )
    out = run_headless(code)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[-2] == "(48, 64, 3) 1 egl"
